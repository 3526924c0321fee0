"""`ros2 run stylepong_policy select_checkpoint`: validate a training run's checkpoints and choose one.

    select_checkpoint --run RUN_DIR [--seeds 10] [--first-seed 900] [--balls 200] [--speed all]
                      [--high-first-seed 950] [--high-seeds N] [--high-balls N]
                      [--dtw DATASET.npz [--min-success RATE [--relative-to BASELINE_ACTOR.pt]]]
                      [--from-iteration N]
                      [--export ACTOR.pt] [--device cpu] [--num-threads 2]

Every numbered checkpoint of the run (RUN_DIR/checkpoints/model_*.pt, written by the training runner
every `runner.save_interval` iterations; keep them with `runner.keep_checkpoints: 0`, or run this while
training) is exported to a temporary actor and evaluated with `evaluate`'s protocol on validation seeds
(`--seeds` seeds from `--first-seed` at `--speed`; with `--high-first-seed`, also at high speeds). Only
seeds below 1000 are accepted: 1000 and up are the evaluation seeds, and a figure reported on them
must not come from the world the checkpoint was chosen in.

Outputs, in RUN_DIR:
  validation.csv       one row per checkpoint and validation setting; rows are only ever appended, and
                       a checkpoint already validated with the same setting is not run again
  validation_curve.png success rates of this setting's rows against training samples, the choice marked
  selection.json       the chosen checkpoint (iteration, samples, file), its figures, the rule and the
                       validation setting
With --export ACTOR.pt the chosen checkpoint's actor is written there (TorchScript, its sidecar JSON,
ONNX), as `train` exports its final actor.

The rule: the highest mean success rate over the validation seeds at `--speed`; a tie goes to the
higher high-speed success rate (when validated), then to the earlier iteration (fewer samples).

A style actor is chosen for how it moves as well: with `--dtw DATASET.npz` each checkpoint's strokes on
the validation balls are also measured against the reference clips (`evaluate --dtw`, per direction:
val_dtw_forward / _leftward / _rightward, and the dataset in dtw_dataset), and with `--min-success RATE`
the rule becomes the style rule (STYLE_RULE): among the checkpoints that return at least RATE of the
validation balls, the one whose strokes lie closest to the demonstrations (the mean of the three
directions' distances); when none returns that many, the success rule above. A success-only choice
takes the latest checkpoint that returns a few more balls, however far its strokes have drifted from
the demonstrations while it learned to. With `--relative-to ACTOR.pt` (a baseline, PPO's actor) that
actor's strokes on the same validation balls are measured too, and the style rule becomes the worst-
direction rule (WORST_RATIO_RULE): the checkpoint whose largest ratio of a direction's distance to the
baseline's is the lowest, the form of the style target (each direction within a fraction of PPO's).
`--from-iteration N` validates and chooses among the checkpoints of iteration N and later only.
"""

from __future__ import annotations

import argparse
import csv
import json
import os
import pathlib
import re
import sys
import tempfile
import time
from dataclasses import dataclass

import torch

from stylepong_common.command_line import require_counts
from stylepong_policy import png
from stylepong_policy.evaluation.strokes import DIRECTIONS
from stylepong_policy.rl.config import config_from_dict, method_of
from stylepong_policy.rl.export import current_spec_contract, export_actor
from stylepong_policy.rl.networks import ActorCritic
from stylepong_policy.rl.runner import CHECKPOINT_DIR, read_checkpoint
from stylepong_sim.world_spec import FIRST_EVALUATION_SEED

CSV_NAME = 'validation.csv'
CURVE_NAME = 'validation_curve.png'
SELECTION_NAME = 'selection.json'
CONFIG_NAME = 'config.yaml'  # train writes the run's configuration under this name
CHECKPOINT_PATTERN = re.compile(r'^model_(\d+)\.pt$')
# An averaged checkpoint's (average_checkpoints) record of the iterations its network is the mean of.
AVERAGED_KEY = 'averaged_iterations'
COLUMNS = (
    'iteration',
    'samples',
    'val_success_all',
    'val_success_high',
    'val_hit_rate_all',
    'val_hit_rate_high',
    'speed',
    'seeds',
    'balls',
    'high_seeds',
    'high_balls',
    'checkpoint',
    'wall_time_s',
)
# With --dtw: the mean DTW distance (rad) of each direction's strokes and the reference dataset. Files
# written before these columns existed keep their header and can still be extended without --dtw.
DTW_COLUMN = {d: f'val_dtw_{d}' for d in DIRECTIONS}
DTW_COLUMNS = tuple(DTW_COLUMN.values()) + ('dtw_dataset',)
# The columns that say how a row was validated: a checkpoint counts as validated only for its setting.
SETTING_COLUMNS = ('speed', 'seeds', 'balls', 'high_seeds', 'high_balls', 'dtw_dataset')
RULE = (
    'highest mean success rate over the validation seeds at the validation speed (val_success_all); '
    'ties: higher val_success_high when validated, then the earlier iteration'
)
STYLE_RULE = (
    'lowest mean DTW distance to the demonstrations over the three directions (val_dtw_*) among '
    'the checkpoints with val_success_all >= {min_success}; when there is none, ' + RULE
)
WORST_RATIO_RULE = (
    'lowest largest ratio, over the three directions, of the DTW distance to the demonstrations '
    '(val_dtw_*) to that of {baseline} on the same validation balls, among the checkpoints with '
    'val_success_all >= {min_success}; when there is none, ' + RULE
)


@dataclass(frozen=True)
class Setting:
    """The validation setting: speed band, seeds and balls (and optionally a high-speed set)."""

    speed: str
    first_seed: int
    seeds: int
    balls: int
    high_first_seed: int | None
    high_seeds: int
    high_balls: int
    dtw_dataset: str = ''  # the reference dataset of the DTW columns, as given ('' : no DTW)

    def row(self) -> dict[str, str]:
        """The setting as it appears in validation.csv (a row validated with DTW also serves a setting
        without it: its success figures are the same measurement)."""
        high = self.high_first_seed is not None
        return {
            'speed': self.speed,
            'seeds': seed_range(self.first_seed, self.seeds),
            'balls': str(self.balls),
            'high_seeds': seed_range(self.high_first_seed, self.high_seeds) if high else '',
            'high_balls': str(self.high_balls) if high else '',
            **({'dtw_dataset': self.dtw_dataset} if self.dtw_dataset else {}),
        }


def seed_range(first: int, count: int) -> str:
    """A seed range as text, e.g. '900-909'."""
    return f'{first}-{first + count - 1}'


def numbered_checkpoints(
    run_dir: pathlib.Path, first: int = 0, last: int | None = None
) -> list[tuple[int, pathlib.Path]]:
    """(iteration, path) of every checkpoints/model_<iteration>.pt with first <= iteration <= last (None: no
    end), in iteration order."""
    found = []
    for path in (run_dir / CHECKPOINT_DIR).glob('model_*.pt'):
        match = CHECKPOINT_PATTERN.match(path.name)
        if match and first <= int(match.group(1)) and (last is None or int(match.group(1)) <= last):
            found.append((int(match.group(1)), path))
    return sorted(found)


def actor_critic_of(checkpoint: dict) -> ActorCritic:
    """The checkpoint's policy network with its weights (and its observation normaliser)."""
    network = ActorCritic(**checkpoint['architecture'])
    network.load_state_dict(checkpoint['model'])
    return network.eval()


def training_info(checkpoint: dict) -> dict:
    """What train writes into an actor's sidecar about its training, from the checkpoint."""
    config = checkpoint.get('config') or {}
    return {
        'method': method_of(config_from_dict(config)),
        'iterations': int(checkpoint['iteration']),
        'samples': int(checkpoint['env_steps']),
        'seed': (config.get('runner') or {}).get('seed'),
        'wall_time_s': round(float(checkpoint['wall_time_s']), 1),
        'devices': sorted({s.get('device') for s in checkpoint.get('sessions') or [] if s.get('device')}),
        'task': config.get('task') or {},
        **({AVERAGED_KEY: checkpoint[AVERAGED_KEY]} if checkpoint.get(AVERAGED_KEY) else {}),
    }


def export_checkpoint(checkpoint: dict, path: pathlib.Path, onnx: bool, extra: dict | None = None) -> pathlib.Path:
    """Export a checkpoint's actor to `path` (and ONNX if asked); returns the actor's path."""
    actor_path, _ = export_actor(
        actor_critic_of(checkpoint),
        path,
        current_spec_contract(),
        training={**training_info(checkpoint), **(extra or {})},
        onnx=onnx,
    )
    return actor_path


def run_evaluation(
    actor: pathlib.Path,
    *,
    seeds: int,
    first_seed: int,
    balls: int,
    speed: str,
    device: str,
    dtw_dataset: str | None = None,
) -> dict:
    """evaluate's result dict for an exported actor (success_rate, hit_rate, per_seed, ..., dtw with a dataset)."""
    from stylepong_policy.evaluation import evaluate

    return evaluate.run_evaluation(
        actor, seeds=seeds, first_seed=first_seed, balls=balls, speed=speed, device=device, dtw_dataset=dtw_dataset
    )


def evaluate_on_validation_balls(actor: pathlib.Path, setting: Setting, device: str) -> dict:
    """evaluate's result for the actor on the setting's validation balls (its speed band, seeds and balls),
    with DTW against the setting's dataset where it has one: a checkpoint and the baseline it is compared
    with are measured alike."""
    return run_evaluation(
        actor,
        seeds=setting.seeds,
        first_seed=setting.first_seed,
        balls=setting.balls,
        speed=setting.speed,
        device=device,
        dtw_dataset=setting.dtw_dataset or None,
    )


def dtw_cells(result: dict) -> dict[str, str]:
    """The DTW columns of a row from evaluate's result (empty where a direction had no stroke)."""
    table = result.get('dtw') or {}
    cells = {}
    for direction in DIRECTIONS:
        mean = (table.get(direction) or {}).get('mean_rad')
        cells[DTW_COLUMN[direction]] = f'{mean:.3f}' if mean is not None else ''
    return cells


def validate_checkpoint(checkpoint: dict, setting: Setting, device: str) -> dict[str, str]:
    """Export the checkpoint to a temporary actor, evaluate it in the setting; the figures of its row."""
    started = time.perf_counter()
    with tempfile.TemporaryDirectory(prefix='select_checkpoint_') as tmp:
        actor = export_checkpoint(checkpoint, pathlib.Path(tmp) / 'actor.pt', onnx=False)
        result = evaluate_on_validation_balls(actor, setting, device)
        high = None
        if setting.high_first_seed is not None:
            high = run_evaluation(
                actor,
                seeds=setting.high_seeds,
                first_seed=setting.high_first_seed,
                balls=setting.high_balls,
                speed='high',
                device=device,
            )
    return {
        'val_success_all': f'{result["success_rate"]:.4f}',
        'val_hit_rate_all': f'{result["hit_rate"]:.4f}',
        'val_success_high': f'{high["success_rate"]:.4f}' if high else '',
        'val_hit_rate_high': f'{high["hit_rate"]:.4f}' if high else '',
        **(dtw_cells(result) if setting.dtw_dataset else {}),
        'wall_time_s': f'{time.perf_counter() - started:.1f}',
    }


# --- validation.csv: append only ---------------------------------------------------------------------
def read_rows(path: pathlib.Path) -> tuple[list[str], list[dict[str, str]]]:
    """The header and rows of validation.csv (the expected columns and no rows if it is missing)."""
    if not path.is_file():
        return list(COLUMNS + DTW_COLUMNS), []
    with path.open(newline='') as stream:
        reader = csv.DictReader(stream)
        return list(reader.fieldnames or COLUMNS), list(reader)


def append_row(path: pathlib.Path, header: list[str], row: dict[str, str]) -> None:
    """One row at the end of the file (the header first if the file is new); earlier rows are untouched."""
    new = not path.is_file() or path.stat().st_size == 0
    with path.open('a', newline='') as stream:
        writer = csv.DictWriter(stream, fieldnames=header, extrasaction='raise', restval='')
        if new:
            writer.writeheader()
        writer.writerow(row)
        stream.flush()
        os.fsync(stream.fileno())


def same_setting(row: dict[str, str], setting: Setting) -> bool:
    """Whether a validation.csv row was measured in this setting."""
    return all((row.get(k) or '') == v for k, v in setting.row().items())


def _rate(text: str | None) -> float:
    return float(text) if text not in (None, '') else float('-inf')


def choose(
    rows: list[dict[str, str]], min_success: float | None = None, baseline_dtw: dict[str, float] | None = None
) -> dict[str, str]:
    """The row the rule picks: RULE, or with a success floor STYLE_RULE (rows with their DTW columns), or
    WORST_RATIO_RULE when the baseline's DTW distance per direction is given."""
    if min_success is not None:
        qualified = [r for r in rows if _rate(r['val_success_all']) >= min_success and mean_dtw(r) is not None]
        style = mean_dtw if baseline_dtw is None else (lambda r: worst_ratio(r, baseline_dtw))
        if qualified:
            return min(qualified, key=lambda r: (style(r), -_rate(r['val_success_all']), int(r['iteration'])))
    return max(
        rows, key=lambda r: (_rate(r['val_success_all']), _rate(r.get('val_success_high')), -int(r['iteration']))
    )


def dtw_by_direction(row: dict[str, str]) -> dict[str, float | None]:
    """A row's DTW distance (rad) per direction; None where it was not measured."""
    return {d: float(row[c]) if row.get(c) else None for d, c in DTW_COLUMN.items()}


def mean_dtw(row: dict[str, str]) -> float | None:
    """The mean of a row's three directions' DTW distances (rad); None unless all three were measured."""
    values = list(dtw_by_direction(row).values())
    return None if None in values else sum(values) / len(values)


def dtw_ratios(row: dict[str, str], baseline_dtw: dict[str, float]) -> dict[str, float]:
    """A row's DTW distance per direction as a fraction of the baseline's on the same balls."""
    return {d: value / baseline_dtw[d] for d, value in dtw_by_direction(row).items()}


def worst_ratio(row: dict[str, str], baseline_dtw: dict[str, float]) -> float:
    """The largest of a row's three ratios to the baseline (dtw_ratios)."""
    return max(dtw_ratios(row, baseline_dtw).values())


def baseline_distances(actor: pathlib.Path, setting: Setting, device: str) -> dict[str, float]:
    """The baseline actor's mean DTW distance (rad) per direction on the setting's validation balls."""
    result = evaluate_on_validation_balls(actor, setting, device)
    missing = [d for d in DIRECTIONS if (result.get('dtw') or {}).get(d, {}).get('mean_rad') is None]
    if missing:
        raise ValueError(f'{actor} made no {", ".join(missing)} stroke on the validation balls')
    return {d: float(result['dtw'][d]['mean_rad']) for d in DIRECTIONS}


def plot_curve(rows: list[dict[str, str]], chosen: dict[str, str], setting: Setting, path: pathlib.Path) -> None:
    """Plot validation success against training samples, marking the chosen checkpoint."""
    import matplotlib

    matplotlib.use('Agg')
    import matplotlib.pyplot as plt

    rows = sorted(rows, key=lambda r: int(r['iteration']))
    samples_m = [int(r['samples']) / 1e6 for r in rows]
    fig, ax = plt.subplots(figsize=(8, 4))
    ax.plot(
        samples_m,
        [float(r['val_success_all']) for r in rows],
        'o-',
        label=f'success, {setting.speed} speeds (seeds {setting.row()["seeds"]})',
    )
    if setting.high_first_seed is not None:
        ax.plot(
            samples_m,
            [float(r['val_success_high']) for r in rows],
            's-',
            label=f'success, high speeds (seeds {setting.row()["high_seeds"]})',
        )
    ax.axvline(
        int(chosen['samples']) / 1e6, color='grey', linestyle='--', label=f'chosen: iteration {chosen["iteration"]}'
    )
    style = [(x, d) for x, d in zip(samples_m, map(mean_dtw, rows)) if d is not None]
    if style:
        dtw_axis = ax.twinx()
        dtw_axis.plot(*zip(*style), 'd:', color='tab:red', label='DTW to the demonstrations, mean of 3 directions')
        dtw_axis.set_ylabel('validation DTW (rad)', color='tab:red')
        dtw_axis.set_ylim(bottom=0.0)
        dtw_axis.legend(loc='upper left')
    ax.set_xlabel('training samples (M)')
    ax.set_ylabel('validation success rate')
    ax.set_ylim(-0.02, 1.02)
    ax.grid(True, alpha=0.3)
    ax.legend(loc='lower right')
    ax.set_title(f'Validation, {setting.balls} balls per seed')
    fig.tight_layout()
    png.save_figure(fig, path, dpi=100)
    plt.close(fig)


# --- command line ------------------------------------------------------------------------------------
def parse_args(argv: list[str] | None) -> argparse.Namespace:
    """The command line of select_checkpoint."""
    parser = argparse.ArgumentParser(
        prog='select_checkpoint',
        description=__doc__.split('\n\n')[0],
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument('--run', required=True, type=pathlib.Path, help='training run directory')
    parser.add_argument('--seeds', type=int, default=10, help='validation seeds')
    parser.add_argument('--first-seed', type=int, default=900, help='first validation seed (< 1000)')
    parser.add_argument('--balls', type=int, default=200, help='balls per seed')
    parser.add_argument('--speed', choices=('all', 'low', 'high'), default='all', help='incoming speed band')
    parser.add_argument('--high-first-seed', type=int, help='also validate at high speeds from this seed (< 1000)')
    parser.add_argument('--high-seeds', type=int, help='high-speed validation seeds (default: --seeds)')
    parser.add_argument('--high-balls', type=int, help='balls per high-speed seed (default: --balls)')
    parser.add_argument(
        '--dtw', metavar='DATASET.npz', help="also measure the strokes' DTW distance to this reference dataset's clips"
    )
    parser.add_argument(
        '--min-success',
        type=float,
        metavar='RATE',
        help='with --dtw: choose by the style rule, among checkpoints returning at least RATE',
    )
    parser.add_argument(
        '--relative-to',
        type=pathlib.Path,
        metavar='BASELINE_ACTOR.pt',
        help='with --min-success: choose by the worst-direction rule, ratios to this actor',
    )
    parser.add_argument(
        '--from-iteration',
        type=int,
        default=0,
        metavar='N',
        help='validate and choose among the checkpoints of iteration N and later only',
    )
    parser.add_argument('--export', type=pathlib.Path, metavar='ACTOR.pt', help="write the chosen checkpoint's actor")
    parser.add_argument('--device', default='cpu', help='torch device of the world')
    parser.add_argument('--num-threads', type=int, default=2, help='torch CPU threads')
    args = parser.parse_args(argv)
    args.high_seeds = args.seeds if args.high_seeds is None else args.high_seeds
    args.high_balls = args.balls if args.high_balls is None else args.high_balls
    require_counts(parser, args, ('seeds', 'balls', 'high_seeds', 'high_balls', 'num_threads'))
    ranges = [('--first-seed', args.first_seed, args.seeds)]
    if args.high_first_seed is not None:
        ranges.append(('--high-first-seed', args.high_first_seed, args.high_seeds))
    if args.min_success is not None and (args.dtw is None or not 0.0 <= args.min_success <= 1.0):
        parser.error('--min-success needs --dtw and a rate between 0 and 1')
    if args.relative_to is not None and args.min_success is None:
        parser.error('--relative-to needs --min-success (and --dtw)')
    if args.relative_to is not None and not args.relative_to.is_file():
        parser.error(f'--relative-to {args.relative_to}: no such actor')
    if args.dtw is not None and not pathlib.Path(args.dtw).is_file():
        parser.error(f'--dtw {args.dtw}: no such reference dataset')
    for flag, first, count in ranges:
        if first < 0:
            parser.error(f'{flag} must not be negative')
        if first + count - 1 >= FIRST_EVALUATION_SEED:
            parser.error(
                f'{flag} {first} with {count} seeds reaches seed {first + count - 1}: validation seeds '
                f'must stay below {FIRST_EVALUATION_SEED} (the evaluation seeds)'
            )
    return args


def main(argv: list[str] | None = None) -> int:
    """Entry point of the select_checkpoint executable."""
    args = parse_args(argv)
    run_dir: pathlib.Path = args.run
    checkpoints = numbered_checkpoints(run_dir, args.from_iteration)
    if not checkpoints:
        print(
            f'select_checkpoint: no numbered checkpoints of iteration {args.from_iteration} or later in '
            f'{run_dir / CHECKPOINT_DIR} (model_*.pt)',
            file=sys.stderr,
        )
        return 2
    torch.set_num_threads(args.num_threads)
    setting = Setting(
        args.speed,
        args.first_seed,
        args.seeds,
        args.balls,
        args.high_first_seed,
        args.high_seeds,
        args.high_balls,
        args.dtw or '',
    )
    csv_path = run_dir / CSV_NAME
    header, rows = read_rows(csv_path)
    missing = [c for c in COLUMNS + (DTW_COLUMNS if args.dtw else ()) if c not in header]
    if missing:
        print(
            f'select_checkpoint: {csv_path} lacks the columns {missing}; rows are only appended, so it is '
            'left as it is (move it aside to start a new one)',
            file=sys.stderr,
        )
        return 2
    done = {int(r['iteration']) for r in rows if same_setting(r, setting)}
    for iteration, path in checkpoints:
        if iteration in done:
            print(f'iteration {iteration}: already validated ({CSV_NAME})', flush=True)
            continue
        try:
            checkpoint = read_checkpoint(path)
        except ValueError as err:
            print(f'select_checkpoint: skipping {path.name}: {err}', file=sys.stderr)
            continue
        row = {
            'iteration': str(int(checkpoint['iteration'])),
            'samples': str(int(checkpoint['env_steps'])),
            'checkpoint': f'{CHECKPOINT_DIR}/{path.name}',
            **setting.row(),
            **validate_checkpoint(checkpoint, setting, args.device),
        }
        append_row(csv_path, header, row)
        rows.append(row)
        print(
            f'iteration {row["iteration"]}: success {row["val_success_all"]} ({setting.speed} speeds)'
            + (f', {row["val_success_high"]} (high speeds)' if row['val_success_high'] else '')
            + (f', DTW {" / ".join(row[c] or "-" for c in DTW_COLUMN.values())} rad' if args.dtw else '')
            + f', {row["wall_time_s"]} s',
            flush=True,
        )

    candidates = [r for r in rows if same_setting(r, setting) and int(r['iteration']) >= args.from_iteration]
    baseline = None
    if args.relative_to is not None:
        baseline = baseline_distances(args.relative_to, setting, args.device)
        distances = ' / '.join(f'{baseline[d]:.3f}' for d in DIRECTIONS)
        print(f'baseline {args.relative_to}: DTW {distances} rad', flush=True)
    chosen = choose(candidates, args.min_success, baseline)
    plot_curve(candidates, chosen, setting, run_dir / CURVE_NAME)
    selection = {
        'iteration': int(chosen['iteration']),
        'samples': int(chosen['samples']),
        'checkpoint': chosen['checkpoint'],
        'val_success_all': float(chosen['val_success_all']),
        'val_success_high': float(chosen['val_success_high']) if chosen['val_success_high'] else None,
        'val_hit_rate_all': float(chosen['val_hit_rate_all']),
        **({'val_dtw_rad': dtw_by_direction(chosen), 'dtw_dataset': args.dtw} if args.dtw else {}),
        **(
            {
                'baseline': {'actor': str(args.relative_to), 'val_dtw_rad': baseline},
                'val_dtw_ratio': {d: round(r, 4) for d, r in dtw_ratios(chosen, baseline).items()},
            }
            if baseline is not None and mean_dtw(chosen) is not None
            else {}
        ),
        'rule': (
            RULE
            if args.min_success is None
            else STYLE_RULE.format(min_success=args.min_success)
            if baseline is None
            else WORST_RATIO_RULE.format(min_success=args.min_success, baseline=args.relative_to)
        ),
        'validation': {
            'speed': setting.speed,
            'seeds': list(range(setting.first_seed, setting.first_seed + setting.seeds)),
            'balls_per_seed': setting.balls,
            'high_seeds': (
                list(range(setting.high_first_seed, setting.high_first_seed + setting.high_seeds))
                if setting.high_first_seed is not None
                else None
            ),
            'high_balls_per_seed': setting.high_balls if setting.high_first_seed is not None else None,
        },
        'candidates': len(candidates),
        'validation_csv': CSV_NAME,
        'validation_curve': CURVE_NAME,
    }
    if args.export is not None:
        chosen_path = run_dir / chosen['checkpoint']
        if not chosen_path.is_file():
            print(
                f'select_checkpoint: the chosen checkpoint {chosen_path} no longer exists; nothing exported',
                file=sys.stderr,
            )
            return 1
        # The sidecar names only files that lie beside the actor: the run's config and this selection when
        # the actor goes into the run directory, neither elsewhere.
        in_run_dir = args.export.parent.resolve() == run_dir.resolve()
        extra = {'selected_iteration': selection['iteration']}
        if in_run_dir:
            extra.update(
                selection=SELECTION_NAME, **({'config': CONFIG_NAME} if (run_dir / CONFIG_NAME).is_file() else {})
            )
        actor = export_checkpoint(read_checkpoint(chosen_path), args.export, onnx=True, extra=extra)
        if in_run_dir:
            selection['exported_actor'] = actor.name
        print(f'exported the actor of iteration {selection["iteration"]} to {actor}', flush=True)
    (run_dir / SELECTION_NAME).write_text(json.dumps(selection, indent=2) + '\n')
    print(
        f'chosen: iteration {selection["iteration"]} ({selection["samples"]} samples), success '
        f'{selection["val_success_all"]:.4f} on seeds {setting.row()["seeds"]} ({setting.speed} speeds); '
        f'{run_dir / SELECTION_NAME}',
        flush=True,
    )
    return 0


if __name__ == '__main__':
    sys.exit(main())
