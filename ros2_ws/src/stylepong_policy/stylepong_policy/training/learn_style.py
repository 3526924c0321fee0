"""`ros2 run stylepong_policy learn_style`: a person's demonstration bags in, a deployable style actor out.

    learn_style BAGS_DIR_OR_DATASET --out RUN [--minutes M] [--device cpu|cuda] [--from ACTOR] [--resume]

One recipe (config/amp.yaml) and nothing to tune. The stages, each recorded in RUN/learn_style.json when
it ends, so that `--resume` (after Ctrl-C, SIGKILL or a power cut) continues from the last one:
  check      the demonstrations (labels, clips per label, joint names, joint limits, rate, length against
             the discriminator's window); a bad bag or folder is refused in one line, before anything else
  dataset    RUN/dataset.npz: the clips at 60 Hz and their x2/x3/x5 speed-ups (build_dataset)
  skill      RUN/skill/: the skill to start from, --from as given, else the skill library's (stylepong_policy.
             skills: the shipped style actor's network and models/skills/) validated against the
             demonstrations on seeds 900 and up and chosen as a candidate is (choose_candidate), with
             room for the success hold: it must return MIN_SUCCESS plus the hold's margin (skill_bar)
  train      RUN/train/: the style learned from that skill with a fresh discriminator and the pose and
             stroke priors, for the training share of the time budget less the skill stage's time; a
             checkpoint every iteration (resumable, with the recipe the run began with) and every
             save_interval iterations (the candidates)
  choose     RUN/choose/: the weight averages of the run's last checkpoints (AVERAGED_SHARES of them) and
             its last checkpoint, validated on seeds 900 and up (below 1000); the one with the lowest mean
             DTW to the demonstrations among those returning MIN_SUCCESS of the balls (else the one that
             returns most)
  export     RUN/actor.pt (+ .json sidecar), RUN/actor.onnx, and RUN/actor_checkpoint.pt (its network and
             the demonstrations behind it: a skill another learn_style --from, or the library, can start from)
  evaluate   RUN/eval/: the new actor, PPO's and the shipped style actor on the evaluation seeds (1000 and
             up), strokes and DTW against the given demonstrations
  report     RUN/report.md and its PNGs (style_report)
A label with no clips is not an error: its balls earn no style term, and the skill returns them with the
stroke it started with (docs/DESIGN.md, "Learning a style").
"""

from __future__ import annotations

import argparse
import json
import pathlib
import shlex
import sys
import time
from dataclasses import dataclass

from stylepong_policy.rl.config import TrainConfig, config_from_dict, load_config

PROG = 'learn_style'
STATE_NAME = 'learn_style.json'
STAGES = ('check', 'dataset', 'skill', 'train', 'choose', 'export', 'evaluate', 'report')
DEFAULT_MINUTES = 60.0
# What is not training, within the budget: checking, the world's compilation, choosing, exporting,
# evaluating and the report (about 100 s on the 2-core CPU), three times that for a loaded machine.
RESERVE_S = 5.0 * 60.0
MIN_TRAIN_S = 60.0
# Candidates (candidates_of): weight averages of the checkpoints in each of the last WINDOWS of SPLIT spans
# of the run and of its last third, and the last checkpoint: 7 validations of about 20 s each here.
SPLIT, WINDOWS = 6, 5
MIN_SUCCESS = 0.92  # validation success a candidate must reach to be chosen for its style
VALIDATION = dict(seeds=4, first_seed=900, balls=200)  # below world_spec.FIRST_EVALUATION_SEED
EVALUATION = dict(seeds=10, first_seed=1000, balls=200)
EVALUATION_HIGH = dict(seeds=5, first_seed=2000, balls=200)
DATASET_NAME = 'dataset.npz'
SKILLS_JSON = 'skills.json'
ACTOR_NAME = 'actor.pt'
ACTOR_CHECKPOINT_NAME = 'actor_checkpoint.pt'
TRAIN_DIR, SKILL_DIR, CHOOSE_DIR, EVAL_DIR = 'train', 'skill', 'choose', 'eval'


class StyleError(Exception):
    """What the user must fix: one line."""


@dataclass(frozen=True)
class Paths:
    """Where a run keeps each of its files (`paths_of`)."""

    run: pathlib.Path
    state: pathlib.Path
    dataset: pathlib.Path
    actor: pathlib.Path
    actor_checkpoint: pathlib.Path
    skill: pathlib.Path
    train: pathlib.Path
    choose: pathlib.Path
    eval: pathlib.Path


def paths_of(run: pathlib.Path) -> Paths:
    """The files of the run in `run`."""
    return Paths(
        run,
        run / STATE_NAME,
        run / DATASET_NAME,
        run / ACTOR_NAME,
        run / ACTOR_CHECKPOINT_NAME,
        run / SKILL_DIR,
        run / TRAIN_DIR,
        run / CHOOSE_DIR,
        run / EVAL_DIR,
    )


def models_dir() -> pathlib.Path:
    """The shipped models (installed share directory, else beside the sources)."""
    from stylepong_policy.training.train import default_config_path

    return default_config_path('amp').parent.parent / 'models'


def skill_checkpoint(given: pathlib.Path) -> pathlib.Path:
    """The training checkpoint --from names: a checkpoint, a learn_style RUN, or an exported actor with its
    <name>_checkpoint.pt beside it."""
    candidates = (
        [given / ACTOR_CHECKPOINT_NAME] if given.is_dir() else [given.with_name(given.stem + '_checkpoint.pt'), given]
    )
    for candidate in candidates:
        if candidate.is_file() and is_training_checkpoint(candidate):
            return candidate
    raise StyleError(
        f'--from {given}: not a training checkpoint, and no {candidates[0].name} beside it '
        f'(an exported actor holds no critic to continue from)'
    )


def is_training_checkpoint(path: pathlib.Path) -> bool:
    """A file torch.save wrote with a network and its architecture (not a TorchScript actor, whose archive
    holds code)."""
    import zipfile

    import torch

    try:
        with zipfile.ZipFile(path) as archive:
            if any('/code/' in name for name in archive.namelist()):
                return False
        data = torch.load(path, map_location='cpu', weights_only=False)
    except (OSError, zipfile.BadZipFile, RuntimeError, EOFError, ValueError):
        return False
    return isinstance(data, dict) and 'model' in data and 'architecture' in data


# --- the run's state ------------------------------------------------------------------------------
def read_state(paths: Paths) -> dict:
    """The run's record of its stages ({} for a new run)."""
    return json.loads(paths.state.read_text()) if paths.state.is_file() else {}


def write_state(paths: Paths, state: dict) -> None:
    """Write the record atomically: a run killed mid-write keeps the previous one."""
    tmp = paths.state.with_name(paths.state.name + '.tmp')
    tmp.write_text(json.dumps(state, indent=2) + '\n')
    tmp.replace(paths.state)


def stage_done(paths: Paths, state: dict, stage: str, seconds: float, **facts) -> None:
    """Record a finished stage, its wall time and facts."""
    state.setdefault('stages', {})[stage] = {'wall_time_s': round(seconds, 1), **facts}
    write_state(paths, state)


def say(text: str) -> None:
    """One line of the command's own output."""
    print(f'[{PROG}] {text}', flush=True)


# --- stages ---------------------------------------------------------------------------------------
def recipe(device: str | None) -> tuple[TrainConfig, pathlib.Path]:
    """The one recipe (config/amp.yaml) and its path, on `device` (None: the config's)."""
    from stylepong_policy.training.train import default_config_path

    path = default_config_path('amp')
    cfg = load_config(path)
    if device is not None:
        cfg.runner.device = device
    cfg.runner.progress_bar = False
    return cfg, path


def require_device(device: str) -> None:
    """StyleError, before anything is written, for a device this machine cannot train on (cuda without CUDA)."""
    from stylepong_policy.training.train import resolve_device

    try:
        resolve_device(device)
    except ValueError as err:
        raise StyleError(str(err)) from err


def check_stage(source: pathlib.Path, cfg: TrainConfig):
    """The checked demonstrations (demo_check.DemonstrationSet); StyleError with one line per bad bag."""
    from stylepong_policy.training import demo_check

    try:
        return demo_check.check_demonstrations(source, window_frames=cfg.amp.sequence_length)
    except demo_check.DemonstrationError as err:
        raise StyleError(str(err)) from err


def dataset_stage(found, paths: Paths) -> dict:
    """RUN/dataset.npz from checked demonstrations: their clips and x2/x3/x5 speed-ups."""
    dataset = found.reference_dataset()
    dataset.save(paths.dataset)
    return {'clips': int(dataset.num_clips), 'frames': int(len(dataset.q)), 'clips_per_label': found.clips_per_label()}


def fingerprint_of(paths: Paths) -> str:
    """The fingerprint of the run's demonstrations (skills.demonstrations_fingerprint of RUN/dataset.npz)."""
    from stylepong_policy.training.dataset import ReferenceDataset
    from stylepong_policy.training.skills import demonstrations_fingerprint

    return demonstrations_fingerprint(ReferenceDataset.load(paths.dataset))


def skill_bar(cfg: TrainConfig) -> float:
    """The validation success a library skill must return to be a start. Training lets success fall by the
    hold's margin below the start's (rl.success_hold), and the choice keeps only candidates returning
    MIN_SUCCESS: a start returning barely MIN_SUCCESS leaves no candidate that has moved towards the style."""
    return MIN_SUCCESS + cfg.amp.hold_success_margin


def skill_stage(paths: Paths, state: dict, device: str, min_success: float) -> dict:
    """The skill to start from (state['skill']): --from as given, else the library's skill whose strokes
    are nearest the demonstrations on the validation seeds, among those returning min_success (skills)."""
    import torch

    from stylepong_policy.training import skills
    from stylepong_policy.training.learn_style_progress import StageBar
    from stylepong_policy.training.select_checkpoint import export_checkpoint

    if state.get('skill'):
        return {'chosen': state['skill'], 'given': True}
    fingerprint = fingerprint_of(paths)
    offered = skills.offered(skills.library(models_dir()), fingerprint)
    paths.skill.mkdir(parents=True, exist_ok=True)
    rows = []
    with StageBar('skill', len(offered), unit='skill') as bar:
        for skill in offered:
            checkpoint = torch.load(skill.path, map_location='cpu', weights_only=False)
            actor = export_checkpoint(checkpoint, paths.skill / f'{skill.name}_actor.pt', onnx=False)
            rows.append({'candidate': skill.name, 'path': str(skill.path.resolve()), **validate(actor, paths, device)})
            bar.advance(1)
    chosen = choose_candidate(rows, min_success)
    (paths.skill / SKILLS_JSON).write_text(
        json.dumps(
            {
                'validation': VALIDATION,
                'min_success': min_success,
                'fingerprint': fingerprint,
                'skills': rows,
                'chosen': chosen['candidate'],
            },
            indent=2,
        )
        + '\n'
    )
    state['skill'] = chosen['path']
    say(f'starting from the skill {chosen["candidate"]}: {describe_skills(rows)}')
    return {
        'chosen': chosen['candidate'],
        'given': False,
        'validation_mean_dtw_rad': {r['candidate']: r['mean_dtw_rad'] for r in rows},
        'validation_success': {r['candidate']: r['success_rate'] for r in rows},
    }


def describe_skills(rows: list[dict]) -> str:
    """One line of the skills validated: each one's mean DTW and success."""

    def dtw(row: dict) -> str:
        return 'no DTW' if row['mean_dtw_rad'] is None else f'{row["mean_dtw_rad"]:.2f} rad'

    return ', '.join(f'{r["candidate"]} {dtw(r)} at {r["success_rate"]:.3f}' for r in rows)


def validate(actor: pathlib.Path, paths: Paths, device: str) -> dict:
    """An exported actor on the validation seeds: its success and DTW to the run's demonstrations (the mean
    over the labels with strokes, and per label)."""
    from stylepong_policy.training.select_checkpoint import run_evaluation

    result = run_evaluation(actor, speed='all', device=device, dtw_dataset=str(paths.dataset), **VALIDATION)
    distances = [d['mean_rad'] for d in result['dtw'].values() if d['mean_rad'] is not None]
    return {
        'success_rate': result['success_rate'],
        'mean_dtw_rad': sum(distances) / len(distances) if distances else None,
        'dtw_rad': {k: v['mean_rad'] for k, v in result['dtw'].items()},
    }


def trained_s(train_dir: pathlib.Path) -> float:
    """The training time a stopped run has behind it (its progress log's last wall time; 0 without one)."""
    from stylepong_policy.rl.logger import CSV_NAME, read_progress

    csv_path = train_dir / CSV_NAME
    wall_times = read_progress(csv_path).get('wall_time_s', []) if csv_path.is_file() else []
    return wall_times[-1] if wall_times else 0.0


def train_stage(
    cfg: TrainConfig, config_path: pathlib.Path, paths: Paths, skill: pathlib.Path, budget_s: float, command: str
) -> dict:
    """Learn the style from the skill until the run's training time reaches budget_s (resumes a run, with the
    recipe it began with: a run started before the recipe changed still fits its checkpoints)."""
    from stylepong_policy.rl.runner import read_checkpoint
    from stylepong_policy.training import train
    from stylepong_policy.training.learn_style_progress import StageBar

    resume = '' if (paths.train / 'checkpoints' / 'last.pt').is_file() else None
    if resume is not None:
        device = cfg.runner.device
        cfg = config_from_dict(read_checkpoint(paths.train)['config'])
        cfg.runner.device = device
    cfg.amp.dataset = str(paths.dataset)
    with StageBar('train', budget_s, initial=trained_s(paths.train) if resume is not None else 0.0) as bar:
        result = train.train_run(
            cfg,
            paths.train,
            'amp',
            config_source=str(config_path),
            resume=resume,
            start_from=None if resume is not None else skill,
            tensorboard=False,
            until_wall_time_s=budget_s,
            on_iteration=bar.iteration,
            command=command,
        )
    runner = result.runner
    if runner.interrupted:
        raise KeyboardInterrupt
    if result.actor_path is None:
        raise StyleError('training completed no iteration within its budget; give more --minutes')
    # The budget ends between numbered checkpoints: the last iteration is a candidate too (and, on a short
    # budget or a slow machine, may be the only one).
    last = runner.checkpoint_dir / f'model_{runner.iteration:06d}.pt'
    if not last.is_file():
        runner.save(last)
    return {
        'iterations': runner.iteration,
        'samples': runner.env_steps,
        'training_time_s': round(runner.wall_time_s, 1),
        'samples_per_s': round(runner.env_steps / max(runner.wall_time_s, 1e-9), 1),
    }


def candidates_of(run_dir: pathlib.Path) -> list[tuple[str, list[int]]]:
    """(name, iterations to average) of each candidate: the weight averages of the numbered checkpoints in
    each of the run's last WINDOWS windows (the run split in SPLIT equal spans), of its last third, and
    its last checkpoint alone. Along a run the style comes closer and returns may fall; the choice among
    these is where the run stands on both (choose_candidate)."""
    from stylepong_policy.training.select_checkpoint import numbered_checkpoints

    iterations = [i for i, _ in numbered_checkpoints(run_dir)]
    if not iterations:
        raise StyleError(f'{run_dir} has no numbered checkpoint to choose from; give more --minutes')
    spans = [
        iterations[round(k * len(iterations) / SPLIT) : round((k + 1) * len(iterations) / SPLIT)]
        for k in range(SPLIT - WINDOWS, SPLIT)
    ]
    spans.append(iterations[-max(2, round(len(iterations) / 3)) :])
    chosen: dict[str, list[int]] = {}
    for span in spans:
        if len(span) > 1:
            chosen.setdefault(f'average_{span[0]}_{span[-1]}', span)
    chosen[f'checkpoint_{iterations[-1]}'] = iterations[-1:]
    return list(chosen.items())


def choose_stage(paths: Paths, device: str) -> dict:
    """Validate each candidate (candidates_of) and keep the choice (choose_candidate)."""
    import torch

    from stylepong_policy.rl.runner import read_checkpoint
    from stylepong_policy.training.average_checkpoints import average_checkpoints
    from stylepong_policy.training.learn_style_progress import StageBar
    from stylepong_policy.training.select_checkpoint import export_checkpoint, numbered_checkpoints

    paths.choose.mkdir(parents=True, exist_ok=True)
    by_iteration = dict(numbered_checkpoints(paths.train))
    rows = []
    candidates = candidates_of(paths.train)
    with StageBar('choose', len(candidates), unit='candidate') as bar:
        for name, iterations in candidates:
            checkpoint = average_checkpoints([read_checkpoint(by_iteration[i]) for i in iterations])
            torch.save(checkpoint, paths.choose / f'{name}.pt')
            actor = export_checkpoint(checkpoint, paths.choose / f'{name}_actor.pt', onnx=False)
            rows.append({'candidate': name, 'iterations': iterations, **validate(actor, paths, device)})
            bar.advance(1)
    chosen = choose_candidate(rows)
    (paths.choose / 'candidates.json').write_text(
        json.dumps(
            {'validation': VALIDATION, 'min_success': MIN_SUCCESS, 'candidates': rows, 'chosen': chosen['candidate']},
            indent=2,
        )
        + '\n'
    )
    return {
        'chosen': chosen['candidate'],
        'validation_success': chosen['success_rate'],
        'validation_mean_dtw_rad': chosen['mean_dtw_rad'],
    }


def choose_candidate(rows: list[dict], min_success: float = MIN_SUCCESS) -> dict:
    """The lowest mean DTW among the rows returning min_success (a row without DTW counts as far); else the
    row that returns most."""
    good = [r for r in rows if r['success_rate'] >= min_success]
    if not good:
        return max(rows, key=lambda r: r['success_rate'])
    return min(good, key=lambda r: float('inf') if r['mean_dtw_rad'] is None else r['mean_dtw_rad'])


def export_stage(paths: Paths, state: dict) -> None:
    """The chosen candidate as RUN/actor.pt, .json, .onnx, and its network as RUN/actor_checkpoint.pt with
    the demonstrations behind it (its skill's and these: skills.LINEAGE_KEY)."""
    import torch

    from stylepong_policy.training import skills
    from stylepong_policy.training.select_checkpoint import export_checkpoint

    chosen = state['stages']['choose']['chosen']
    checkpoint = torch.load(paths.choose / f'{chosen}.pt', map_location='cpu', weights_only=False)
    export_checkpoint(checkpoint, paths.actor, onnx=True, extra={'learn_style': {'candidate': chosen}})
    start = torch.load(state['skill'], map_location='cpu', weights_only=False)
    lineage = skills.lineage_after(start, fingerprint_of(paths))
    slim = {**checkpoint, 'optimizer': None, 'motion_prior': None, skills.LINEAGE_KEY: lineage}
    torch.save(slim, paths.actor_checkpoint)


def evaluate_stage(paths: Paths, device: str) -> dict:
    """The new actor, PPO's and the shipped style actor on the evaluation seeds, against the demonstrations."""
    from stylepong_policy.reports import style_report
    from stylepong_policy.training.learn_style_progress import StageBar

    paths.eval.mkdir(parents=True, exist_ok=True)
    actors = {'style': paths.actor, 'ppo': models_dir() / 'ppo_actor.pt', 'shipped': models_dir() / 'amp_actor.pt'}
    jobs = [(name, actor, 'all', EVALUATION) for name, actor in actors.items()]
    jobs.append(('style', paths.actor, 'high', EVALUATION_HIGH))
    with StageBar('evaluate', len(jobs), unit='evaluations') as bar:
        for name, actor, speed, setting in jobs:
            files = style_report.eval_files(paths.run, name)
            out = files.all_speeds_json if speed == 'all' else files.high_speeds_json
            result = evaluate_with_strokes(
                actor, speed, setting, device, paths.dataset, files.strokes_npz if speed == 'all' else None
            )
            out.write_text(json.dumps(result, indent=2) + '\n')
            bar.advance(1)
    style = json.loads(style_report.eval_files(paths.run, 'style').all_speeds_json.read_text())
    return {
        'success_rate': style['success_rate'],
        'dtw_rad': {k: v['mean_rad'] for k, v in style.get('dtw', {}).items()},
    }


def evaluate_with_strokes(
    actor: pathlib.Path,
    speed: str,
    setting: dict,
    device: str,
    dataset: pathlib.Path,
    strokes_path: pathlib.Path | None,
) -> dict:
    """evaluate's summary of an actor with DTW against `dataset`, its strokes saved when a path is given."""
    from stylepong_policy.evaluation import evaluate
    from stylepong_policy.rl.export import load_actor

    loaded = load_actor(actor)
    evaluation = evaluate.evaluate_actor(loaded, speed=speed, device=device, **setting)
    summary = evaluate.summarise(evaluation, dataset=evaluate.load_reference(dataset), dataset_path=dataset)
    if strokes_path is not None:
        summary['strokes_file'] = evaluate.save_evaluation_strokes(strokes_path, evaluation, loaded)
    return summary


def report_stage(paths: Paths, state: dict) -> pathlib.Path:
    """RUN/report.md and its figures."""
    from stylepong_policy.evaluation.evaluate import portable_path
    from stylepong_policy.reports import style_report

    stages = state.get('stages', {})
    missing = [label for label, count in stages.get('dataset', {}).get('clips_per_label', {}).items() if not count]
    notes = [
        f'Demonstrations: {stages.get("check", {}).get("summary", "")}.',
        f'Recipe: {portable_path(state.get("config", "?"))}, from the skill '
        f'{portable_path(state.get("skill", "?"))}; command: `{state.get("command")}`.',
    ]
    if (paths.skill / SKILLS_JSON).is_file():
        chosen = json.loads((paths.skill / SKILLS_JSON).read_text())
        notes.append(
            f'The skill was chosen from the library on the validation seeds (mean DTW to these '
            f'demonstrations and success): {describe_skills(chosen["skills"])}.'
        )
    if missing:
        notes.append(
            f'No clip labelled {", ".join(missing)}: those balls earned no style term in training and are '
            'returned with the stroke of the skill the run started from; no DTW is measured for them.'
        )
    return style_report.write_report(
        paths.run,
        dataset_path=paths.dataset,
        timings_s={k: v['wall_time_s'] for k, v in stages.items()},
        checkpoints={'train': stages.get('train'), 'choose': stages.get('choose')},
        notes=notes,
    )


# --- the command ----------------------------------------------------------------------------------
def parse_args(argv: list[str] | None) -> argparse.Namespace:
    """The command line of learn_style."""
    parser = argparse.ArgumentParser(
        prog=PROG, description=__doc__.split('\n\n')[0], formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument(
        'source',
        type=pathlib.Path,
        metavar='BAGS_DIR_OR_DATASET',
        help='a folder of labelled demonstration bags, or a build_dataset .npz',
    )
    parser.add_argument('--out', required=True, type=pathlib.Path, help='run directory')
    parser.add_argument(
        '--minutes',
        type=float,
        default=DEFAULT_MINUTES,
        help=f'wall-time budget of the whole command (default {DEFAULT_MINUTES:g})',
    )
    parser.add_argument('--device', choices=('cpu', 'cuda'), default=None, help='torch device (default: cpu)')
    skill_help = (
        'the skill to start from: a learn_style RUN, its actor.pt, or a training checkpoint '
        '(default: the nearest skill of the library, validated against the demonstrations)'
    )
    parser.add_argument('--from', dest='start_from', type=pathlib.Path, metavar='ACTOR', help=skill_help)
    parser.add_argument('--resume', action='store_true', help='continue the run in --out from its last stage')
    return parser.parse_args(argv)


def training_budget_s(minutes: float, spent_s: float = 0.0) -> float:
    """The training stage's share of the budget: all but RESERVE_S (a quarter of a short budget) and the
    spent_s that choosing the skill took."""
    total_s = minutes * 60.0
    return max(MIN_TRAIN_S, total_s - min(RESERVE_S, 0.25 * total_s) - spent_s)


def run(args: argparse.Namespace, command: str) -> pathlib.Path:
    """Every stage not yet done; returns the report's path. StyleError for what the user must fix."""
    paths = paths_of(args.out)
    state = read_state(paths)
    if state and not args.resume:
        raise StyleError(
            f'{args.out} already holds a learn_style run; pass --resume to continue it or choose another --out'
        )
    if args.resume and not state:
        say(f'nothing to resume in {args.out}; starting a new run')
    if args.minutes <= 0:
        raise StyleError(f'--minutes must be positive, got {args.minutes}')
    skill = None
    if state:  # a resumed run keeps what it was started with
        source, minutes = pathlib.Path(state['source']), float(state['minutes'])
        device = state['device']
    else:
        source, minutes, device = args.source, args.minutes, args.device or 'cpu'
        if not source.exists():
            raise StyleError(f'{source}: no such folder or dataset')
        skill = skill_checkpoint(args.start_from) if args.start_from is not None else None
    require_device(device)
    cfg, config_path = recipe(device)
    started = time.perf_counter()
    found = check_stage(source, cfg)  # again on resume: it is quick, and the bags may have changed
    if 'check' not in state.get('stages', {}):
        args.out.mkdir(parents=True, exist_ok=True)
        state.update(
            source=str(source.resolve()),
            minutes=minutes,
            device=device,
            skill=str(skill.resolve()) if skill is not None else None,
            command=command,
            config=str(config_path),
        )
        stage_done(paths, state, 'check', time.perf_counter() - started, summary=found.describe())
    say(f'demonstrations: {found.describe()}')
    for stage in STAGES[1:]:
        if stage in state.get('stages', {}):
            continue
        started = time.perf_counter()
        say(f'stage {STAGES.index(stage) + 1}/{len(STAGES)}: {stage}')
        facts = run_stage(stage, paths, state, found, cfg, config_path, minutes, device)
        stage_done(paths, state, stage, time.perf_counter() - started, **(facts or {}))
    return paths.run / 'report.md'


def run_stage(
    stage: str,
    paths: Paths,
    state: dict,
    found,
    cfg: TrainConfig,
    config_path: pathlib.Path,
    minutes: float,
    device: str,
) -> dict | None:
    """Run one stage after the check; returns the facts its record keeps."""
    if stage == 'dataset':
        return dataset_stage(found, paths)
    if stage == 'skill':
        return skill_stage(paths, state, device, skill_bar(cfg))
    if stage == 'train':
        spent_s = state['stages']['skill']['wall_time_s']
        return train_stage(
            cfg, config_path, paths, pathlib.Path(state['skill']), training_budget_s(minutes, spent_s), state['command']
        )
    if stage == 'choose':
        return choose_stage(paths, device)
    if stage == 'export':
        export_stage(paths, state)
        return None
    if stage == 'evaluate':
        return evaluate_stage(paths, device)
    report_stage(paths, state)
    return None


def main(argv: list[str] | None = None) -> int:
    """Entry point of the learn_style executable."""
    args = parse_args(argv)
    command = shlex.join([PROG] + (sys.argv[1:] if argv is None else list(argv)))
    try:
        report = run(args, command)
    except StyleError as err:
        print(f'{PROG}: {err}', file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(
            f'{PROG}: interrupted; the last checkpoint is kept. Continue with: '
            f'{PROG} {shlex.quote(str(args.source))} --out {shlex.quote(str(args.out))} --resume',
            file=sys.stderr,
        )
        return 130
    say(f'done: {args.out / ACTOR_NAME} (+ .json, .onnx); report {report}')
    say(f'play it: ros2 run stylepong_policy player --ros-args -p actor:={args.out / "actor.onnx"}')
    return 0


if __name__ == '__main__':
    sys.exit(main())
