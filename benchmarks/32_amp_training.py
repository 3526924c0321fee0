#!/usr/bin/env python3
"""AMP training throughput end to end, and the discriminator's share of an iteration.

Runs the real runner with the motion prior (`train --method amp`'s path: rollouts, style reward from
the discriminator on every step's windows, PPO update, discriminator updates, checkpoint and CSV log)
on `stylepong_policy.training.task.make_env` with the shipped config/amp.yaml, the reference motions built from
the shipped clips, N environments on the CPU; prints one Markdown section for BENCHMARKS.md.
"""

from __future__ import annotations

import contextlib
import io
import os
import pathlib
import sys
import tempfile

os.environ.setdefault('OMP_WAIT_POLICY', 'PASSIVE')  # as `train` does (see train.py), before torch loads

import torch

from stylepong_common import markdown

NUM_ENVS = int(os.environ.get('BENCH_AMP_NUM_ENVS', 1024))
WARMUP_ITERATIONS = 1
MEASURED_ITERATIONS = 2
ROOT = pathlib.Path(__file__).resolve().parent.parent
SHARES = ('world_share', 'policy_share', 'learn_share', 'style_share')  # the table's columns of the shares


def measure(run_dir: pathlib.Path) -> dict[str, float]:
    from stylepong_policy.rl.config import load_config
    from stylepong_policy.rl.runner import OnPolicyRunner
    from stylepong_policy.rl.throughput import benchmark_env, measure_throughput
    from stylepong_policy.training.train import default_config_path, make_motion_prior

    cfg = load_config(default_config_path('amp'))
    env = benchmark_env(cfg, NUM_ENVS)
    prior, _ = make_motion_prior(cfg, env, run_dir, torch.device('cpu'))
    runner = OnPolicyRunner(env, cfg, run_dir, tensorboard=False, motion_prior=prior)
    return {
        **measure_throughput(runner, WARMUP_ITERATIONS, MEASURED_ITERATIONS),
        'hidden': cfg.policy.actor_hidden_dims,
        'disc_hidden': cfg.amp.hidden_dims,
        'length': cfg.amp.sequence_length,
        'updates': cfg.amp.updates_per_iteration,
        'batch': cfg.amp.batch_size,
    }


def main() -> int:
    torch.set_num_threads(2)
    load_before = os.getloadavg()[0]
    # The dataset build and the runner print progress; only this script's Markdown goes to stdout.
    with tempfile.TemporaryDirectory() as run_dir, contextlib.redirect_stdout(io.StringIO()):
        r = measure(pathlib.Path(run_dir))
    print('## AMP training throughput (end to end)\n')
    print(
        '`benchmarks/32_amp_training.py`: the runner with the motion prior on '
        '`stylepong_policy.training.task.make_env`, '
        f'N = {NUM_ENVS} environments on the CPU (torch {torch.__version__}, 2 threads), the shipped '
        f'`config/amp.yaml` (actor and critic {r["hidden"]}, discriminator {r["disc_hidden"]} on windows of '
        f'{r["length"]} arm states, {r["updates"]} discriminator steps of {r["batch"]} + {r["batch"]} windows '
        f'per iteration), reference motions built from `ros2_ws/bags`; {WARMUP_ITERATIONS} warm-up iteration, '
        f'then the mean of {MEASURED_ITERATIONS}. Load average before the run: {load_before:.1f}.\n'
    )
    header = [
        'samples/s',
        's/iteration',
        'world',
        'policy inference',
        'PPO update',
        'discriminator (scoring + updates)',
    ]
    cells = [f'{r["samples_per_s"]:,.0f}', f'{r["iteration_s"]:.1f}', *(f'{100 * r[share]:.0f} %' for share in SHARES)]
    print('\n'.join(markdown.table(header, [cells])))
    print(
        '\nShares are of training wall time. The shipped style actors were trained on a GPU; their summaries '
        '(`models/amp_summary.json`, `models/amp_noaug_summary.json`) give the samples per second there.'
    )
    return 0


if __name__ == '__main__':
    sys.exit(main())
