"""`ros2 run stylepong_policy style_confusion`: which demonstration set each actor's strokes are nearest to.

    style_confusion --actor NAME=ACTOR.pt ... --set NAME=BAGS_DIR_OR_DATASET ... --baseline PPO_ACTOR.pt
                    [--seeds 10] [--first-seed 1000] [--balls 200] --out results/

An actor is an exported actor.pt or a training checkpoint, such as a learned style's skill in the library
(models/skills/NAME.pt), which is exported to a temporary actor first: the same network, the same actions.

Every actor (and the baseline) is evaluated once, by evaluate's protocol (nominal batched world, the same
balls for every actor), keeping its strokes. Each stroke is compared by DTW with the clips of its own
label in each set (all speed factors; the nearest clip counts), exactly as `evaluate --dtw` does, and an
actor's distance to a set is the mean over its strokes (per direction, and over every stroke whose label
the set has). Unnormalised DTW grows with the clips' length, so sets are compared through the baseline's
(PPO's: no style) distance to each: the normalised distance is actor / baseline on the same set. An
actor's nearest set is the one with the smallest normalised distance; its margin is how much larger the
next one is (the difference, and the ratio). An actor named like a set is meant to be nearest to it.

A set is a folder of bags (built into a dataset with build_dataset in a temporary folder, x2/x3/x5
included) or a dataset .npz. Beside the distances, how each actor's blade meets its balls and how each set's
demonstrations meet theirs (stylepong_policy.evaluation.contacts: where a stroke meets the ball sets much of its
distance). Writes OUT/style_confusion.md, .json and .png (the normalised matrix).

Every set with an actor of its name, but for the shipped style actor's (`shipped`, stylepong_policy.training.
skills.SHIPPED), is a learned style: OUT/styles/<set>/ gets its report (style_report.write_report_of: report.md,
report.json and the PNGs, strips of frames included) from the evaluations above, that actor beside the
baseline (as PPO) and the actor named `shipped` on that set's demonstrations, and the actor as actor.onnx (the
player's default). The report's run section is the record of how the actor was learned when one lies beside
its file (a skill's <name>.json, a learn_style run's learn_style.json). Without an actor named `shipped` no
report is written.
Exit status 0, 2 for invalid arguments (a missing file, an actor that does not fit, a set with no clip).
"""

from __future__ import annotations

import argparse
import contextlib
import dataclasses
import datetime
import io
import json
import pathlib
import sys
import tempfile
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import NoReturn

import numpy as np

from stylepong_common import markdown
from stylepong_common.command_line import exit_with_run, require_counts, ros2_run_line
from stylepong_policy import png
from stylepong_policy.evaluation import contacts, evaluate, style_metrics
from stylepong_policy.evaluation.strokes import DIRECTIONS, Stroke
from stylepong_policy.reports import style_report
from stylepong_policy.training import skills
from stylepong_policy.training.dataset import ReferenceDataset
from stylepong_recording.bag_errors import one_line

BASELINE = 'baseline'
OVERALL = 'overall'
MARKDOWN_NAME = 'style_confusion.md'
JSON_NAME = 'style_confusion.json'
PNG_NAME = 'style_confusion.png'
STYLES_DIR = 'styles'  # OUT/styles/<set>/: each learned style's report and ONNX actor
ONNX_NAME = 'actor.onnx'


# ---------------------------------------------------------------------------------------------------
# Distances


@dataclass(frozen=True)
class SetDistance:
    """An actor's mean DTW to one set: per direction and over every stroke with clips of its label (rad)."""

    by_direction_rad: dict[str, float | None]
    overall_rad: float | None
    strokes_compared: int


def set_distance(
    strokes: Sequence[Stroke], dataset: ReferenceDataset, matches: Sequence[style_metrics.DtwMatch | None] | None = None
) -> SetDistance:
    """Each stroke's DTW to the nearest clip of its own label in `dataset` (evaluate's), averaged; `matches`:
    the strokes' evaluate.nearest_matches against it when already measured."""
    if matches is None:
        matches = evaluate.nearest_matches(strokes, evaluate.references_by_direction(dataset))
    by_direction = {}
    for direction in DIRECTIONS:
        distances = [m.distance for s, m in zip(strokes, matches) if m is not None and s.direction == direction]
        by_direction[direction] = float(np.mean(distances)) if distances else None
    compared = [m.distance for m in matches if m is not None]
    return SetDistance(
        by_direction_rad=by_direction,
        overall_rad=float(np.mean(compared)) if compared else None,
        strokes_compared=len(compared),
    )


def normalised(distance: float | None, baseline: float | None) -> float | None:
    """An actor's distance over the baseline's on the same set (None when either is missing)."""
    return distance / baseline if distance is not None and baseline else None


@dataclass(frozen=True)
class Verdict:
    """An actor's nearest set by normalised distance, and by how much the next one is further."""

    nearest: str | None
    margin: float | None  # next smallest minus smallest normalised distance
    margin_ratio: float | None  # next smallest over smallest
    own_set: str | None  # the set named like the actor, if any
    nearest_is_own: bool | None


def verdict(actor: str, row: Mapping[str, float | None]) -> Verdict:
    """The nearest set of one actor's row of normalised distances (sets without a value are left out)."""
    ranked = sorted((value, name) for name, value in row.items() if value is not None)
    own = actor if actor in row else None
    if not ranked:
        return Verdict(None, None, None, own, None)
    best_value, best = ranked[0]
    margin = ratio = None
    if len(ranked) > 1:
        margin = ranked[1][0] - best_value
        ratio = ranked[1][0] / best_value if best_value else None
    return Verdict(best, margin, ratio, own, None if own is None else best == own)


# ---------------------------------------------------------------------------------------------------
# Inputs


def parse_named(text: str) -> tuple[str, pathlib.Path]:
    """'NAME=PATH' -> (NAME, PATH)."""
    name, separator, path = text.partition('=')
    if not separator or not name.strip() or not path.strip():
        raise argparse.ArgumentTypeError(f'{text!r} is not NAME=PATH')
    return name.strip(), pathlib.Path(path.strip())


def load_set(name: str, path: pathlib.Path, folder: pathlib.Path) -> ReferenceDataset:
    """A set's dataset: a .npz as it is, or bags built by build_dataset into `folder` (ValueError: why not)."""
    from stylepong_policy.training import build_dataset

    if not path.exists():
        raise ValueError(f'set {name}: {path} does not exist')
    if path.is_file() and path.suffix == '.npz':
        return evaluate.load_reference(path)
    output = folder / f'{name}.npz'
    log = io.StringIO()
    with contextlib.redirect_stdout(log), contextlib.redirect_stderr(log):
        status = build_dataset.run([str(path), '-o', str(output)])
    if status != 0 or not output.is_file():
        last = log.getvalue().strip().splitlines()[-1:] or ['no output']
        raise ValueError(f'set {name}: build_dataset found no usable clip in {path} ({last[0]})')
    return evaluate.load_reference(output)


def clips_per_label(dataset: ReferenceDataset) -> dict[str, int]:
    """Original (x1) clips of each direction's label."""
    labels = dataset.label[dataset.speed_factor == 1].tolist()
    return {d: labels.count(d) for d in DIRECTIONS}


# ---------------------------------------------------------------------------------------------------
# Outputs


def _number(value: float | None, digits: int = 3) -> str:
    return 'n/a' if value is None else f'{value:.{digits}f}'


def render_markdown(record: dict) -> str:
    """style_confusion.md from the JSON record."""
    sets = list(record['sets'])
    actors = list(record['actors'])
    raw = record['dtw_rad']
    norm = record['normalised']
    lines = [
        "# Style confusion: each actor's strokes against each demonstration set",
        '',
        f'Generated {record["generated"]} by `{record["command"]}` ({record["wall_time_s"]:.0f} s).',
        '',
        f'Setting: {record["setting"]}. Each stroke is compared by DTW with the clips of its own label in a '
        f"set (all speed factors, the nearest counts: `{evaluate.DTW_CALL}`); an actor's distance to a set is "
        f'the mean over its strokes whose label the set has. Normalised: over the baseline '
        f"(`{record['baseline']}`, no style) on the same set, since unnormalised DTW grows with the clips' "
        'length.',
        '',
        'Sets (original clips per label forward / leftward / rightward):',
        '',
    ]
    lines += [
        f'- `{name}`: `{info["path"]}`, ' + ' / '.join(str(info['clips_per_label'][d]) for d in DIRECTIONS)
        for name, info in record['sets'].items()
    ]
    rows = []
    for a in actors:
        nearest = record['verdicts'][a]['nearest']
        cells = [f'**{_number(norm[a][s][OVERALL])}**' if nearest == s else _number(norm[a][s][OVERALL]) for s in sets]
        rows.append(
            [
                f'`{a}`',
                *cells,
                f'`{nearest}`' if nearest else 'n/a',
                _number(record['verdicts'][a]['margin']),
                _number(record['verdicts'][a]['margin_ratio'], 2),
            ]
        )
    lines += [
        '',
        '## Normalised distance (actor / baseline on the same set; smaller is nearer)',
        '',
        *markdown.table(['Actor'] + [f'`{s}`' for s in sets] + ['nearest', 'margin', 'next / nearest'], rows),
        '',
        f'![confusion]({PNG_NAME})',
        '',
    ]
    own = [(a, v) for a, v in record['verdicts'].items() if v['own_set'] is not None]
    if own:
        lines += [
            'Actors named like a set: '
            + '; '.join(f'`{a}` is {"" if v["nearest_is_own"] else "NOT "}nearest its own set' for a, v in own)
            + '.',
            '',
        ]
    if record.get('reports'):
        lines += [
            f"Each learned style's report (its strokes beside its demonstrations, the baseline's and "
            f"`{skills.SHIPPED}`'s, from these evaluations) and its actor as ONNX: "
            + ', '.join(
                f'[`{name}`]({files["report"]}) ([{ONNX_NAME}]({files["onnx"]}))'
                for name, files in record['reports'].items()
            )
            + '.',
            '',
        ]
    lines += [
        '## Mean DTW (rad, not normalised)',
        '',
        *markdown.table(
            ['Actor'] + [f'`{s}`' for s in sets],
            [[f'`{a}`'] + [_number(raw[a][s][OVERALL], 2) for s in sets] for a in [*actors, BASELINE]],
        ),
        '',
        '## Normalised distance per direction',
        '',
        *markdown.table(
            ['Actor', 'Set'] + list(DIRECTIONS),
            [[f'`{a}`', f'`{s}`'] + [_number(norm[a][s][d]) for d in DIRECTIONS] for a in actors for s in sets],
        ),
        '',
    ]
    blades = record['contacts']
    rows = {f'`{s}` demonstrations': blades['demonstrations'][s] for s in sets}
    rows |= {f'`{a}`': blades['actors'][a] for a in [*actors, BASELINE]}
    lines += [
        '## The blade at contact',
        '',
        contacts.TABLE_NOTE,
        '',
        *markdown.table(*contacts.contact_table(rows)),
        '',
    ]
    return '\n'.join(lines)


def heatmap(path: pathlib.Path, record: dict) -> pathlib.Path:
    """The normalised matrix, actors by sets, each cell annotated."""
    import matplotlib

    matplotlib.use('Agg')
    import matplotlib.pyplot as plt

    sets, actors = list(record['sets']), list(record['actors'])
    values = np.array(
        [
            [
                np.nan if record['normalised'][a][s][OVERALL] is None else record['normalised'][a][s][OVERALL]
                for s in sets
            ]
            for a in actors
        ],
        dtype=float,
    )
    figure, ax = plt.subplots(figsize=(max(5.5, 2.5 + 1.5 * len(sets)), 2.0 + 0.7 * len(actors)))
    image = ax.imshow(values, cmap='viridis_r', aspect='auto')
    low, high = np.nanmin(values), np.nanmax(values)
    for i, actor in enumerate(actors):
        for j, name in enumerate(sets):
            value = values[i, j]
            # viridis_r is dark at the high end: light text there.
            dark = not np.isnan(value) and high > low and (value - low) / (high - low) > 0.5
            ax.text(
                j,
                i,
                'n/a' if np.isnan(value) else f'{value:.3f}',
                ha='center',
                va='center',
                color='w' if dark else 'k',
                fontsize=9,
                fontweight='bold' if record['verdicts'][actor]['nearest'] == name else 'normal',
            )
    ax.set_xticks(range(len(sets)), sets)
    ax.set_yticks(range(len(actors)), actors)
    ax.set_xlabel('demonstration set')
    ax.set_ylabel('actor')
    figure.colorbar(image, ax=ax, label="mean DTW / baseline's")
    ax.set_title(
        f"Style confusion, normalised by the baseline (bold: each actor's nearest set)\n"
        f'{record["setting"].split("; ", 1)[1]}',
        fontsize=8,
    )
    figure.tight_layout()
    png.save_figure(figure, path, dpi=110)
    plt.close(figure)
    return path


# ---------------------------------------------------------------------------------------------------
# Each learned style's report


def reported_styles(actors: Sequence[str], sets: Sequence[str]) -> list[str]:
    """The sets that get a report: those with an actor of their name, but for the shipped style actor's (the
    one every report compares with); none without it."""
    if skills.SHIPPED not in actors:
        return []
    return [name for name in sets if name in actors and name != skills.SHIPPED]


def learned_record(actor: pathlib.Path) -> tuple[pathlib.Path, dict] | None:
    """How an actor was learned, when a record of it lies beside its file: ship_skill's <name>.json beside a
    skill of the library (models/skills/<name>.pt), or learn_style.json in a learn_style run beside its
    actor.pt. Returned as (that file, {'command', 'started_from', 'stages': {stage: its facts}}); else None."""
    from stylepong_policy.training import learn_style

    beside = actor.with_suffix('.json')
    if beside.is_file():
        shipped = json.loads(beside.read_text())
        # ship_skill's record holds the run's command and stages; an exported actor's sidecar holds neither.
        if isinstance(shipped, dict) and 'command' in shipped and 'choose' in shipped:
            stages = {k: v for k, v in shipped.items() if isinstance(v, dict) and 'wall_time_s' in v}
            return beside, {
                'command': shipped['command'],
                'started_from': shipped.get('started_from'),
                'stages': stages,
            }
    state = actor.parent / learn_style.STATE_NAME
    if actor.name == learn_style.ACTOR_NAME and state.is_file():
        run = json.loads(state.read_text())
        return state, {
            'command': run.get('command'),
            'stages': run.get('stages', {}),
            'started_from': run.get('skill') and evaluate.portable_path(run['skill']),
        }
    return None


def report_notes(name: str, record: Mapping, learned: tuple[pathlib.Path, dict] | None) -> list[str]:
    """The lines under a style report's title: the demonstrations, the actors, how the style was learned."""
    from stylepong_policy.training.learn_style import describe_skills

    clips = record['sets'][name]['clips_per_label']
    notes = [
        f'Demonstrations: `{record["sets"][name]["path"]}`, original clips per label: '
        + ', '.join(f'{d} {clips[d]}' for d in DIRECTIONS)
        + '.',
        f'The new style actor is `{record["actors"][name]["path"]}` ({ONNX_NAME} beside this report, for the '
        f'player), PPO `{record["baseline"]}`, the shipped style actor '
        f'`{record["actors"][skills.SHIPPED]["path"]}`; at all speeds only (no high-speed evaluation here).',
    ]
    if learned is None:
        return notes + [
            "No record of how it was learned lies beside it (a skill's <name>.json, a learn_style "
            "run's learn_style.json): no run section."
        ]
    path, facts = learned
    notes.append(
        f'Learned by `{facts["command"]}` from the skill `{facts["started_from"]}`; the run section is its '
        f'record, `{evaluate.portable_path(path)}`.'
    )
    chosen = facts['stages'].get('skill', {})
    if chosen.get('validation_mean_dtw_rad'):
        rows = [
            {'candidate': k, 'mean_dtw_rad': v, 'success_rate': chosen['validation_success'][k]}
            for k, v in chosen['validation_mean_dtw_rad'].items()
        ]
        notes.append(
            'The skill was chosen from the library on the validation seeds (mean DTW to these '
            f'demonstrations and success): {describe_skills(rows)}.'
        )
    return notes


def write_style_report(
    folder: pathlib.Path,
    name: str,
    record: Mapping,
    evaluations: Mapping[str, evaluate.Evaluation],
    summaries: Mapping[str, dict],
    dataset: ReferenceDataset,
    actor,
) -> pathlib.Path:
    """FOLDER/report.md (style_report) of the style `name` from the evaluations and their summaries against
    its set (evaluate.summarise with DTW; both by actor name, the baseline standing for PPO), and
    FOLDER/actor.onnx of `actor` (the style's LoadedActor); returns the report's path."""
    from stylepong_policy.rl.export import write_onnx_of

    roles = {'style': name, 'ppo': BASELINE, 'shipped': skills.SHIPPED}
    set_path = record['sets'][name]['path']
    results = {
        role: style_report.ActorResults(
            name=role,
            all_speeds=summaries[actor_name],
            high_speeds=None,
            strokes=evaluations[actor_name].strokes,
            rate_hz=evaluate.ACTION_RATE_HZ,
        )
        for role, actor_name in roles.items()
    }
    learned = learned_record(pathlib.Path(actor.path))
    timings, checkpoints = {}, None
    if learned is not None:
        stages = learned[1]['stages']
        timings = {stage: facts['wall_time_s'] for stage, facts in stages.items() if 'wall_time_s' in facts}
        checkpoints = {'train': stages.get('train'), 'choose': stages.get('choose')}
    report = style_report.write_report_of(
        folder,
        results,
        dataset,
        dataset_name=set_path,
        source=f'`{record["command"]}`, from its evaluations',
        timings_s=timings,
        checkpoints=checkpoints,
        notes=report_notes(name, record, learned),
    )
    write_onnx_of(actor, folder / ONNX_NAME)
    return report


def load_named_actor(name: str, path: pathlib.Path, folder: pathlib.Path):
    """--actor's file: an exported actor (rl.export.load_actor), or a training checkpoint such as a skill of
    the library (models/skills/<name>.pt: the network a learned style ships as) exported into `folder`
    first, as learn_style validates skills. Either computes the same actions; the loaded actor keeps the
    path given (the records name it, and one file given twice is evaluated once)."""
    from stylepong_policy.rl.export import file_sha256, load_actor
    from stylepong_policy.training.learn_style import is_training_checkpoint

    if not is_training_checkpoint(path):
        return load_actor(path)
    import torch

    from stylepong_policy.training.select_checkpoint import export_checkpoint

    checkpoint = torch.load(path, map_location='cpu', weights_only=False)
    loaded = load_actor(export_checkpoint(checkpoint, folder / f'{name}.pt', onnx=False))
    # The file it came from is the checkpoint, not the temporary export: an ONNX file written from it names
    # that (its exported_from), the same bytes whatever the export was called.
    return dataclasses.replace(
        loaded, path=path, metadata={**loaded.metadata, 'actor_file': path.name, 'actor_sha256': file_sha256(path)}
    )


# ---------------------------------------------------------------------------------------------------
# Command line


def _add_named_paths_option(parser: argparse.ArgumentParser, flag: str, metavar: str, help_text: str) -> None:
    """A required option given one or more times as NAME=PATH (parse_named), listed in args.<flag>s."""
    parser.add_argument(
        flag,
        dest=f'{flag.removeprefix("--")}s',
        action='append',
        type=parse_named,
        required=True,
        metavar=metavar,
        help=f'{help_text} (repeat)',
    )


def build_parser() -> argparse.ArgumentParser:
    """The command line of style_confusion."""
    from stylepong_sim.world_spec import EVALUATION_BALLS_PER_SEED, EVALUATION_SEEDS, FIRST_EVALUATION_SEED

    parser = argparse.ArgumentParser(prog='style_confusion', description=__doc__.split('\n\n')[0])
    _add_named_paths_option(
        parser, '--actor', 'NAME=ACTOR.pt', 'an exported actor, or a training checkpoint such as models/skills/NAME.pt'
    )
    _add_named_paths_option(parser, '--set', 'NAME=BAGS_DIR_OR_DATASET', 'a demonstration set')
    parser.add_argument(
        '--baseline',
        required=True,
        type=pathlib.Path,
        metavar='ACTOR.pt',
        help='the actor every distance is normalised by (PPO: no style)',
    )
    parser.add_argument('--seeds', type=int, default=EVALUATION_SEEDS, help='evaluation seeds (default %(default)s)')
    parser.add_argument(
        '--first-seed', type=int, default=FIRST_EVALUATION_SEED, help='first seed (default %(default)s)'
    )
    parser.add_argument(
        '--balls', type=int, default=EVALUATION_BALLS_PER_SEED, help='balls per seed (default %(default)s)'
    )
    parser.add_argument('--out', required=True, type=pathlib.Path, help='folder for the .md, .json and .png')
    parser.add_argument('--device', default='cpu', help='torch device of the world')
    parser.add_argument('--num-threads', type=int, default=2, help='torch CPU threads')
    return parser


def _unique(parser: argparse.ArgumentParser, items: Sequence[tuple[str, pathlib.Path]], what: str) -> dict:
    names = [name for name, _ in items]
    repeated = sorted({n for n in names if names.count(n) > 1})
    if repeated:
        parser.error(f'--{what} name {repeated[0]!r} given twice')
    if BASELINE in names:
        parser.error(f'--{what} name {BASELINE!r} is reserved for --baseline')
    return dict(items)


def run(argv: Sequence[str] | None = None) -> int:
    """Evaluate, measure and write (module docstring); returns the exit code."""
    import torch

    from stylepong_policy.rl.export import ActorMismatchError

    argv = list(sys.argv[1:] if argv is None else argv)
    parser = build_parser()
    args = parser.parse_args(argv)
    require_counts(parser, args, ('seeds', 'balls', 'num_threads'))
    actor_paths = _unique(parser, args.actors, 'actor')
    set_paths = _unique(parser, args.sets, 'set')
    torch.set_num_threads(args.num_threads)
    started = time.perf_counter()

    def log(message: str) -> None:
        print(f'[style_confusion {time.perf_counter() - started:6.1f} s] {message}', flush=True)

    with tempfile.TemporaryDirectory(prefix='style_confusion_') as folder:
        try:
            loaded = {
                name: load_named_actor(name, path, pathlib.Path(folder))
                for name, path in {**actor_paths, BASELINE: args.baseline}.items()
            }
        except (ActorMismatchError, OSError, ValueError, KeyError) as error:
            print(f'style_confusion: {one_line(error)}', file=sys.stderr)
            return 2
        try:
            datasets = {name: load_set(name, path, pathlib.Path(folder)) for name, path in set_paths.items()}
        except (OSError, KeyError, ValueError) as error:
            print(f'style_confusion: {error}', file=sys.stderr)
            return 2
    for name, dataset in datasets.items():
        log(f'set {name}: {dataset.num_clips} clips, originals per label {clips_per_label(dataset)}')

    # One evaluation per actor file: an actor given twice (or the baseline among the actors) runs once.
    evaluation_of_file: dict[pathlib.Path, evaluate.Evaluation] = {}
    success_of_file: dict[pathlib.Path, float] = {}
    evaluations: dict[str, evaluate.Evaluation] = {}
    success: dict[str, float] = {}
    for name, actor in loaded.items():
        key = pathlib.Path(actor.path).resolve()
        if key not in evaluation_of_file:
            evaluation = evaluate.evaluate_actor(
                actor, seeds=args.seeds, first_seed=args.first_seed, balls=args.balls, device=args.device
            )
            evaluation_of_file[key] = evaluation
            success_of_file[key] = evaluate.summarise(evaluation)['success_rate']
            log(f'{name}: evaluated, success {success_of_file[key]:.3f} over {len(evaluation.strokes)} balls')
        evaluations[name], success[name] = evaluation_of_file[key], success_of_file[key]
    strokes = {name: evaluation.strokes for name, evaluation in evaluations.items()}

    reported = reported_styles(list(actor_paths), list(datasets))
    if not reported and any(name in actor_paths for name in datasets if name != skills.SHIPPED):
        log(f'no style report: each compares with the shipped style actor, and no --actor is named {skills.SHIPPED!r}')
    raw: dict[str, dict[str, dict]] = {name: {} for name in loaded}
    # The reports' summaries (set -> actor -> evaluate.summarise with DTW), from the matches measured here:
    # a report measures no DTW of its own. Matches carry their DTW paths, too many to keep for every pair.
    summaries: dict[str, dict[str, dict]] = {name: {} for name in reported}
    for set_name, dataset in datasets.items():
        references = evaluate.references_by_direction(dataset)
        for name in loaded:
            matches = evaluate.nearest_matches(strokes[name], references)
            distance = set_distance(strokes[name], dataset, matches)
            raw[name][set_name] = {
                **distance.by_direction_rad,
                OVERALL: distance.overall_rad,
                'strokes_compared': distance.strokes_compared,
            }
            if set_name in reported and name in (set_name, BASELINE, skills.SHIPPED):
                summaries[set_name][name] = evaluate.summarise(
                    evaluations[name], dataset=dataset, dataset_path=set_paths[set_name], matches=matches
                )
        log(f'set {set_name}: DTW of every actor measured')
    columns = (*DIRECTIONS, OVERALL)
    norm = {
        name: {s: {c: normalised(raw[name][s][c], raw[BASELINE][s][c]) for c in columns} for s in datasets}
        for name in actor_paths
    }
    verdicts = {name: verdict(name, {s: norm[name][s][OVERALL] for s in datasets}).__dict__ for name in actor_paths}

    last_seed = args.first_seed + args.seeds - 1
    seeds = f'seed {args.first_seed}' if args.seeds == 1 else f'seeds {args.first_seed}-{last_seed}'
    record = {
        'command': ros2_run_line('stylepong_policy', 'style_confusion', argv),
        'generated': datetime.date.today().isoformat(),
        'setting': f'{evaluate.WORLDS[False]}; {seeds} x {args.balls} balls; all speeds; deterministic actors',
        'baseline': evaluate.portable_path(args.baseline),
        'actors': {
            name: {'path': evaluate.portable_path(path), 'success_rate': success[name]}
            for name, path in actor_paths.items()
        },
        'baseline_success_rate': success[BASELINE],
        'sets': {
            name: {
                'path': evaluate.portable_path(path),
                'clips': datasets[name].num_clips,
                'clips_per_label': clips_per_label(datasets[name]),
            }
            for name, path in set_paths.items()
        },
        'dtw_rad': raw,
        'normalised': norm,
        'verdicts': verdicts,
        'dtw_call': evaluate.DTW_CALL,
        'contacts': {
            'demonstrations': {
                name: contacts.mean_blades(contacts.demonstrated_contacts(dataset))
                for name, dataset in datasets.items()
            },
            'actors': {name: contacts.mean_blades(contacts.actor_contacts(strokes[name])) for name in loaded},
        },
    }
    args.out.mkdir(parents=True, exist_ok=True)
    record['reports'] = {}
    for name in reported:
        folder = args.out / STYLES_DIR / name
        write_style_report(folder, name, record, evaluations, summaries[name], datasets[name], loaded[name])
        record['reports'][name] = {
            'report': f'{STYLES_DIR}/{name}/{style_report.REPORT_MD}',
            'onnx': f'{STYLES_DIR}/{name}/{ONNX_NAME}',
        }
        log(f'{name}: wrote {evaluate.portable_path(folder / style_report.REPORT_MD)}, its PNGs and {ONNX_NAME}')
    record['wall_time_s'] = round(time.perf_counter() - started, 1)
    (args.out / JSON_NAME).write_text(json.dumps(record, indent=2) + '\n')
    (args.out / MARKDOWN_NAME).write_text(render_markdown(record))
    heatmap(args.out / PNG_NAME, record)
    for name, v in verdicts.items():
        log(f'{name}: nearest {v["nearest"]} (margin {_number(v["margin"])})')
    log(f'wrote {evaluate.portable_path(args.out / MARKDOWN_NAME)}, {JSON_NAME} and {PNG_NAME}')
    return 0


def main(argv: Sequence[str] | None = None) -> NoReturn:
    """Entry point of the style_confusion executable (exit code 130 on Ctrl-C)."""
    exit_with_run('style_confusion', run, argv)


if __name__ == '__main__':
    main()
