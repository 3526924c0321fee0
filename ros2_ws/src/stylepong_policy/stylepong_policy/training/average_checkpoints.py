"""`ros2 run stylepong_policy average_checkpoints`: the weight average of the end of a training run.

    average_checkpoints --run RUN_DIR --from-iteration N [--to-iteration M] --out AVERAGED_RUN_DIR

A policy trained against a moving target (the discriminator of a style run) does not settle: from one
saved checkpoint to the next it trades a few returned balls for a little style and back, and which
checkpoint a validation set favours is partly luck. The mean of the weights of the checkpoints along
the end of a run lies inside that wandering (stochastic weight averaging: "Averaging Weights Leads to
Wider Optima and Better Generalization", Izmailov et al.); for the shipped `amp` actor it returned more
validation balls than any of the checkpoints it averages (docs/DESIGN.md, Known limits).

The mean is taken by torch's own stochastic-weight-averaging tool, `torch.optim.swa_utils.AveragedModel`,
over the parameters and the buffers (the observation normalisers' running mean and variance) of every
numbered checkpoint RUN_DIR/checkpoints/model_<i>.pt with N <= i <= M (M: the last).

AVERAGED_RUN_DIR is written as a run of its own, so that select_checkpoint validates it and
`ship_run` ships it like any run:
  checkpoints/model_<M>.pt  the averaged network with the last checkpoint's records (iteration, samples,
                            wall time: the average needs the whole run), no optimiser or discriminator
                            state (it is not a point training passed through), and the averaged
                            iterations under `averaged_iterations`
  summary.json              the run's summary with `averaged_from` (the run and the iterations)
  config.yaml, progress.csv, learning_curve.png   copied from the run
"""

from __future__ import annotations

import argparse
import json
import pathlib
import shutil
import sys

import torch
from torch.optim.swa_utils import AveragedModel

from stylepong_policy.rl.logger import CSV_NAME
from stylepong_policy.rl.runner import CHECKPOINT_DIR, read_checkpoint
from stylepong_policy.training.select_checkpoint import AVERAGED_KEY, actor_critic_of, numbered_checkpoints
from stylepong_policy.training.train import CONFIG_NAME, CURVE_NAME, SUMMARY_NAME

# What the averaged run directory takes over unchanged from the run (when the run has it).
COPIED = (CONFIG_NAME, CSV_NAME, CURVE_NAME)


def checkpoints_between(run_dir: pathlib.Path, first: int, last: int | None) -> list[tuple[int, pathlib.Path]]:
    """(iteration, path) of the run's numbered checkpoints with first <= iteration <= last (None: no end)."""
    chosen = numbered_checkpoints(run_dir, first, last)
    if not chosen:
        raise ValueError(
            f'{run_dir / CHECKPOINT_DIR} has no numbered checkpoint between iterations {first} '
            f'and {"its end" if last is None else last}'
        )
    return chosen


def average_checkpoints(checkpoints: list[dict]) -> dict:
    """One checkpoint whose network is the mean of these checkpoints' networks (parameters and buffers),
    with the last checkpoint's records; ValueError if their networks differ."""
    if not checkpoints:
        raise ValueError('nothing to average')
    architectures = {repr(c['architecture']) for c in checkpoints}
    if len(architectures) > 1:
        raise ValueError(f'the checkpoints hold different networks: {sorted(architectures)}')
    networks = [actor_critic_of(c) for c in checkpoints]
    averaged = AveragedModel(networks[0], use_buffers=True)
    for network in networks:
        averaged.update_parameters(network)
    last = checkpoints[-1]
    return {
        **last,
        'model': averaged.module.state_dict(),
        'optimizer': None,
        'motion_prior': None,
        AVERAGED_KEY: [int(c['iteration']) for c in checkpoints],
    }


def write_averaged_run(
    run_dir: pathlib.Path, first: int, last: int | None, out: pathlib.Path
) -> tuple[pathlib.Path, list[int]]:
    """Average the run's checkpoints from `first` to `last` into the run directory `out`; returns the
    averaged checkpoint's path and the iterations averaged."""
    if (out / CHECKPOINT_DIR).is_dir() and any((out / CHECKPOINT_DIR).iterdir()):
        raise ValueError(f'{out} already holds checkpoints; choose another --out')
    chosen = checkpoints_between(run_dir, first, last)
    checkpoint = average_checkpoints([read_checkpoint(path) for _, path in chosen])
    path = out / CHECKPOINT_DIR / f'model_{checkpoint["iteration"]:06d}.pt'
    path.parent.mkdir(parents=True, exist_ok=True)
    torch.save(checkpoint, path)
    for name in COPIED:
        if (run_dir / name).is_file():
            shutil.copyfile(run_dir / name, out / name)
    summary_path = run_dir / SUMMARY_NAME
    summary = json.loads(summary_path.read_text()) if summary_path.is_file() else {}
    summary['averaged_from'] = {'run': str(run_dir), 'iterations': checkpoint[AVERAGED_KEY]}
    (out / SUMMARY_NAME).write_text(json.dumps(summary, indent=2) + '\n')
    return path, checkpoint[AVERAGED_KEY]


def main(argv: list[str] | None = None) -> int:
    """Entry point of the average_checkpoints executable."""
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--run', required=True, type=pathlib.Path, help='the training run directory')
    parser.add_argument('--from-iteration', required=True, type=int, help='the first checkpoint averaged')
    parser.add_argument('--to-iteration', type=int, default=None, help="the last one (default: the run's last)")
    parser.add_argument('--out', required=True, type=pathlib.Path, help='the averaged run directory to write')
    args = parser.parse_args(argv)
    try:
        path, iterations = write_averaged_run(args.run, args.from_iteration, args.to_iteration, args.out)
    except (ValueError, FileNotFoundError) as err:
        print(f'average_checkpoints: {err}', file=sys.stderr)
        return 2
    span = f'iterations {iterations[0]}-{iterations[-1]}'
    print(f'average_checkpoints: {len(iterations)} checkpoints ({span}) averaged into {path}', flush=True)
    return 0


if __name__ == '__main__':
    sys.exit(main())
