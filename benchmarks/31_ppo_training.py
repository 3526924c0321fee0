#!/usr/bin/env python3
"""PPO training throughput end to end in the batched world, and the share of wall time spent in the world.

Runs the real runner (rollouts with the policy under inference mode, GAE, PPO update, checkpoint and
CSV log) on `stylepong_policy.training.task.make_env` with the shipped config's PPO settings, for the paper's
network sizes and a smaller pair, and prints one Markdown section for BENCHMARKS.md.
"""

from __future__ import annotations

import os
import sys
import tempfile
import time
from typing import TYPE_CHECKING

os.environ.setdefault('OMP_WAIT_POLICY', 'PASSIVE')  # as `train` does (see train.py), before torch loads

import torch

from stylepong_common import markdown

if TYPE_CHECKING:
    from stylepong_policy.rl.config import PPOConfig

NUM_ENVS = int(os.environ.get('BENCH_PPO_NUM_ENVS', 4096))
WARMUP_ITERATIONS = 1
MEASURED_ITERATIONS = 2
NETWORKS = ([512, 256, 128], [256, 128, 64])
SHARES = ('world_share', 'policy_share', 'learn_share')  # the table's columns of measure_throughput's shares


def measure(hidden_dims: list[int]) -> tuple[dict[str, float], PPOConfig]:
    """measure_throughput's figures for these hidden sizes, and the PPO settings they were trained with."""
    from stylepong_policy.rl.config import load_config
    from stylepong_policy.rl.runner import OnPolicyRunner
    from stylepong_policy.rl.throughput import benchmark_env, measure_throughput
    from stylepong_policy.training.train import default_config_path

    cfg = load_config(default_config_path())
    cfg.policy.actor_hidden_dims = list(hidden_dims)
    cfg.policy.critic_hidden_dims = list(hidden_dims)
    env = benchmark_env(cfg, NUM_ENVS)
    with tempfile.TemporaryDirectory() as run_dir:
        runner = OnPolicyRunner(env, cfg, run_dir, tensorboard=False)
        throughput = measure_throughput(runner, WARMUP_ITERATIONS, MEASURED_ITERATIONS)
    return throughput, cfg.ppo


def main() -> int:
    torch.set_num_threads(2)
    load_before = os.getloadavg()[0]
    rows = []
    for dims in NETWORKS:
        started = time.perf_counter()
        throughput, ppo = measure(dims)
        rows.append((dims, throughput, time.perf_counter() - started))
    print('## PPO training throughput (end to end)\n')
    print(
        '`benchmarks/31_ppo_training.py`: the runner on `stylepong_policy.training.task.make_env` '
        f'with N = {NUM_ENVS} environments on the CPU (torch {torch.__version__}, 2 threads), the shipped '
        '`config/ppo.yaml` '
        f'({ppo.num_steps_per_env} steps per env per iteration, {ppo.num_learning_epochs} epochs x '
        f'{ppo.num_mini_batches} minibatches); {WARMUP_ITERATIONS} warm-up iteration, then the mean of '
        f'{MEASURED_ITERATIONS}. '
        f'Samples = policy steps x environments. Actor and critic have the same hidden sizes. '
        f'Load average before the run: {load_before:.1f} (other work on the 2 cores slows every figure).\n'
    )
    header = ['hidden sizes', 'samples/s', 's/iteration', 'world share', 'policy inference (rollout)', 'PPO update']
    cells = [
        [
            str(dims),
            f'{r["samples_per_s"]:,.0f}',
            f'{r["iteration_s"]:.1f}',
            *(f'{100 * r[share]:.0f} %' for share in SHARES),
        ]
        for dims, r, _ in rows
    ]
    print('\n'.join(markdown.table(header, cells)))
    print('\nShares are of training wall time (the rest, a few %, is GAE, logging and checkpoints).')
    return 0


if __name__ == '__main__':
    sys.exit(main())
