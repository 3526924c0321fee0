"""How fast the on-policy runner trains on this machine, and where an iteration's wall time goes (no rclpy).

What benchmarks/31_ppo_training.py and 32_amp_training.py report: a few iterations warm up (first-call
allocations, lazy imports), then the mean over the measured ones of the runner's own timings
(OnPolicyRunner.learn's statistics: world_s, policy_s, learn_s, style_s and iteration_time_s).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING

from stylepong_policy.rl.runner import OnPolicyRunner, seed_everything

if TYPE_CHECKING:
    from stylepong_policy.rl.config import TrainConfig
    from stylepong_policy.training.task import TableTennisEnv

BENCHMARK_SEED = 1
# A save interval no benchmark reaches: the runner writes no checkpoint while it is timed.
NO_CHECKPOINT_ITERATIONS = 10**6

# The runner's timed parts of an iteration (style_s: the discriminator's, zero without a motion prior).
PARTS = ('world_s', 'policy_s', 'learn_s', 'style_s')


def measure_throughput(
    runner: OnPolicyRunner, warmup_iterations: int, measured_iterations: int, parts: Sequence[str] = PARTS
) -> dict[str, float]:
    """Train warmup_iterations, then measured_iterations more one at a time; samples_per_s (environment
    steps per second of training), iteration_s (mean wall time of an iteration) and, for each part
    'name_s', 'name_share' (its share of the wall time)."""
    runner.learn(warmup_iterations, progress_bar=False)
    first_step = runner.env_steps
    totals = dict.fromkeys((*parts, 'iteration_time_s'), 0.0)
    for it in range(measured_iterations):
        stats = runner.learn(warmup_iterations + it + 1, progress_bar=False)
        for key in totals:
            totals[key] += stats[key]
    wall_s = totals['iteration_time_s']
    shares = {part.removesuffix('_s') + '_share': totals[part] / wall_s for part in parts}
    return {
        'samples_per_s': (runner.env_steps - first_step) / wall_s,
        'iteration_s': wall_s / measured_iterations,
        **shares,
    }


def benchmark_env(cfg: TrainConfig, num_envs: int) -> TableTennisEnv:
    """The training world of `cfg` with num_envs environments on the CPU, as the benchmarks time it: every
    generator seeded with BENCHMARK_SEED, and cfg set to match (num_envs, no checkpoint during the run)."""
    from stylepong_policy.training import task

    cfg.task['num_envs'] = num_envs
    cfg.runner.save_interval = NO_CHECKPOINT_ITERATIONS
    seed_everything(BENCHMARK_SEED)
    return task.make_env(task.TaskConfig(**cfg.task), 'cpu', BENCHMARK_SEED)
