#!/usr/bin/env python3
"""Copy a training run's chosen actor and its record into the package's models/ folder, as shipped.

    python3 tools/ship_run.py --run runs/amp --name amp [--models-dir ros2_ws/src/stylepong_policy/models]

Needs `train` to have written the run (RUN/summary.json, config.yaml, progress.csv, learning_curve.png)
and `select_checkpoint --run RUN --export RUN/selected/<name>_actor.pt` to have chosen and exported the
actor (RUN/selection.json, validation.csv, validation_curve.png). Writes <name>_actor.pt/.json/.onnx,
<name>_config.yaml, <name>_progress.csv, <name>_learning_curve.png, <name>_validation.csv,
<name>_validation_curve.png and <name>_summary.json: train's summary with select_checkpoint's choice
under `selection`, and the names of the files beside it. Then it evaluates the shipped actor on the
evaluation protocol's seeds (EVALUATIONS: `evaluate`, nominal batched world) into <name>_eval_all.json and
<name>_eval_high.json (`--no-evaluate` skips this). Nothing is typed by hand; run it again after either
tool and the shipped files follow.
"""
from __future__ import annotations

import argparse
import json
import pathlib
import shutil
import subprocess
import sys

ROOT = pathlib.Path(__file__).resolve().parent.parent
COPIED = {'config.yaml': 'config.yaml', 'progress.csv': 'progress.csv', 'learning_curve.png': 'learning_curve.png',
          'validation.csv': 'validation.csv', 'validation_curve.png': 'validation_curve.png'}
ACTOR_SUFFIXES = ('.pt', '.json', '.onnx')
# The evaluation protocol of the shipped actors (docs/DESIGN.md, "Evaluation protocol"): file suffix ->
# evaluate's flags. Evaluation seeds are 1000 and up; a run is only shipped once its recipe is final.
EVALUATIONS = {
    'eval_all': ['--seeds', '10', '--first-seed', '1000', '--balls', '200', '--speed', 'all'],
    'eval_high': ['--seeds', '10', '--first-seed', '2000', '--balls', '200', '--speed', 'high'],
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
        written.append(pathlib.Path(shutil.copyfile(run / source, models / f'{name}_{target}')))
    summary.update(actor=f'{name}_actor.pt', config=f'{name}_config.yaml', progress=f'{name}_progress.csv',
                   learning_curve=f'{name}_learning_curve.png', validation=f'{name}_validation.csv',
                   validation_curve=f'{name}_validation_curve.png', selection=selection)
    path = models / f'{name}_summary.json'
    path.write_text(json.dumps(summary, indent=2) + '\n')
    written.append(path)
    return written


def evaluate_shipped(name: str, models: pathlib.Path) -> list[pathlib.Path]:
    """Run `evaluate` on the shipped actor for every entry of EVALUATIONS; returns the JSON files written.

    Run from the repository root, so that evaluate records the actor's path relative to it."""
    actor = (models / f'{name}_actor.pt').resolve()
    written = []
    for suffix, flags in EVALUATIONS.items():
        path = (models / f'{name}_{suffix}.json').resolve()
        subprocess.run(['ros2', 'run', 'stylepong_policy', 'evaluate', '--actor', str(actor), *flags,
                        '--json', str(path)], cwd=ROOT, check=True, stdout=subprocess.DEVNULL)
        written.append(path)
    return written


def main() -> int:
    """Command line of ship_run."""
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--run', required=True, type=pathlib.Path)
    parser.add_argument('--name', required=True, help='amp, amp_noaug, ppo: the shipped files\' prefix')
    parser.add_argument('--models-dir', type=pathlib.Path, default=ROOT / 'ros2_ws/src/stylepong_policy/models')
    parser.add_argument('--no-evaluate', action='store_true', help='copy only; skip the evaluations')
    args = parser.parse_args()
    try:
        written = ship(args.run, args.name, args.models_dir)
        if not args.no_evaluate:
            written += evaluate_shipped(args.name, args.models_dir)
    except (OSError, ValueError, KeyError, subprocess.CalledProcessError) as err:
        print(f'ship_run: {err}', file=sys.stderr)
        return 2
    for path in written:
        print(f'wrote {path}')
    return 0


if __name__ == '__main__':
    sys.exit(main())
