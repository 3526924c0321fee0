"""Copy a training run's chosen actor and its record into the package's models/ folder, as shipped.

    ros2 run stylepong_policy ship_run --run runs/amp --name amp [--models-dir ros2_ws/src/stylepong_policy/models]

Needs `train` to have written the run (RUN/summary.json, config.yaml, progress.csv, learning_curve.png)
and `select_checkpoint --run RUN --export RUN/selected/<name>_actor.pt` to have chosen and exported the
actor (RUN/selection.json, validation.csv, validation_curve.png). Writes <name>_actor.pt/.json/.onnx,
<name>_config.yaml, <name>_progress.csv.xz (the run's progress.csv, xz-compressed: rl.logger.read_progress
reads either), <name>_learning_curve.png, <name>_validation.csv, <name>_validation_curve.png (both PNGs palettised,
stylepong_policy.png) and <name>_summary.json: train's summary with select_checkpoint's choice under
`selection`, and the names of the files beside it. Then it evaluates the shipped actor on the
evaluation protocol's seeds (EVALUATIONS: `evaluate`'s run_evaluation, nominal batched world) into
<name>_eval_all.json and <name>_eval_high.json (`--no-evaluate` skips this). Nothing is typed by hand;
run it again after either tool and the shipped files follow.
"""

from __future__ import annotations

import json
import lzma
import pathlib
import shutil
import sys

from stylepong_policy import png
from stylepong_policy.paths import MODELS, REPOSITORY
from stylepong_policy.shipping import shipping_parser

# The run's file -> the shipped one's name after <name>_: the training log is the largest file shipped
# (over 1 MB plain), so it is kept compressed: xz keeps a third of it (gzip two fifths).
COPIED = {
    'config.yaml': 'config.yaml',
    'progress.csv': 'progress.csv.xz',
    'learning_curve.png': 'learning_curve.png',
    'validation.csv': 'validation.csv',
    'validation_curve.png': 'validation_curve.png',
}
ACTOR_SUFFIXES = ('.pt', '.json', '.onnx')
# The evaluation protocol of the shipped actors (docs/DESIGN.md, "Evaluation protocol"): file suffix ->
# run_evaluation's arguments. Evaluation seeds are 1000 and up; a run is only shipped once its recipe is final.
EVALUATIONS = {
    'eval_all': {'seeds': 10, 'first_seed': 1000, 'balls': 200, 'speed': 'all'},
    'eval_high': {'seeds': 10, 'first_seed': 2000, 'balls': 200, 'speed': 'high'},
}


def ship(run: pathlib.Path, name: str, models: pathlib.Path) -> list[pathlib.Path]:
    """Copy a run's selected actor and its records into the models folder; returns the files written."""
    summary = json.loads((run / 'summary.json').read_text())
    selection = json.loads((run / 'selection.json').read_text())
    actor = run / 'selected' / f'{name}_actor.pt'
    missing = [p for p in [actor.with_suffix(s) for s in ACTOR_SUFFIXES] + [run / f for f in COPIED] if not p.is_file()]
    if missing:
        raise FileNotFoundError('missing: ' + ', '.join(str(p) for p in missing))
    written = []
    for suffix in ACTOR_SUFFIXES:
        written.append(pathlib.Path(shutil.copyfile(actor.with_suffix(suffix), models / f'{name}_actor{suffix}')))
    for source, target in COPIED.items():
        written.append(ship_file(run / source, models / f'{name}_{target}'))
    summary.update(
        actor=f'{name}_actor.pt',
        config=f'{name}_config.yaml',
        progress=f'{name}_progress.csv.xz',
        learning_curve=f'{name}_learning_curve.png',
        validation=f'{name}_validation.csv',
        validation_curve=f'{name}_validation_curve.png',
        selection=selection,
    )
    path = models / f'{name}_summary.json'
    path.write_text(json.dumps(summary, indent=2) + '\n')
    written.append(path)
    return written


def ship_file(source: pathlib.Path, target: pathlib.Path) -> pathlib.Path:
    """Copy a run's file to `target` in the form models/ keeps: xz-compressed for a .xz target (no time in the
    format: the same CSV always ships as the same bytes), a PNG palettised (png.shrink: a run from before
    train wrote small PNGs ships as small ones), anything else as it is."""
    if target.suffix == '.xz':
        with open(source, 'rb') as plain, lzma.open(target, 'wb') as packed:
            shutil.copyfileobj(plain, packed)
        return target
    shutil.copyfile(source, target)
    return png.shrink(target) if target.suffix == '.png' else target


def in_repository(path: pathlib.Path) -> str:
    """A path as the shipped records write it: relative to the repository when inside it, else its file name
    alone (as evaluate's portable_path does), so that a record never carries this machine's folders."""
    resolved = path.resolve()
    return resolved.relative_to(REPOSITORY).as_posix() if resolved.is_relative_to(REPOSITORY) else resolved.name


def evaluation_command(actor: str, json_path: str, arguments: dict) -> list[str]:
    """The `evaluate` flags that repeat one entry of EVALUATIONS from the repository root."""
    flags = ['--actor', actor]
    for key, value in arguments.items():
        flags += [f'--{key.replace("_", "-")}', str(value)]
    return flags + ['--json', json_path]


def evaluate_shipped(name: str, models: pathlib.Path) -> list[pathlib.Path]:
    """Evaluate the shipped actor for every entry of EVALUATIONS (evaluate's run_evaluation, in this
    process); returns the JSON files written, each with the `evaluate` command that repeats it."""
    from stylepong_policy.evaluation import evaluate  # torch and the batched world: only when evaluating

    actor = models / f'{name}_actor.pt'
    written = []
    for suffix, arguments in EVALUATIONS.items():
        path = models / f'{name}_{suffix}.json'
        summary = evaluate.run_evaluation(actor, **arguments)
        summary['actor'] = in_repository(actor)
        summary['command'] = evaluate.command_line(evaluation_command(summary['actor'], in_repository(path), arguments))
        write_json(summary, path)
        written.append(path)
    return written


def write_json(summary: dict, path: pathlib.Path) -> None:
    """An evaluation's summary in `evaluate --json`'s format (not printed: the shipped files are the record)."""
    path.write_text(json.dumps(summary, indent=2) + '\n')


def ship_run(run: pathlib.Path, name: str, models: pathlib.Path = MODELS, evaluate: bool = True) -> list[pathlib.Path]:
    """Ship a run (`ship`) and, unless `evaluate` is false, evaluate the shipped actor; the files written."""
    written = ship(run, name, models)
    if evaluate:
        written += evaluate_shipped(name, models)
    return written


def main(argv: list[str] | None = None) -> int:
    """Command line of ship_run."""
    name_help = "amp, amp_noaug, ppo: the shipped files' prefix"
    parser = shipping_parser('ship_run', __doc__.split('\n\n')[0], None, name_help)
    parser.add_argument('--no-evaluate', action='store_true', help='copy only; skip the evaluations')
    args = parser.parse_args(argv)
    try:
        written = ship_run(args.run, args.name, args.models_dir, evaluate=not args.no_evaluate)
    except (OSError, ValueError, KeyError) as err:
        print(f'ship_run: {err}', file=sys.stderr)
        return 2
    for path in written:
        print(f'wrote {path}')
    return 0


if __name__ == '__main__':
    sys.exit(main())
