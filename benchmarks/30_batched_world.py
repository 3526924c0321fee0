#!/usr/bin/env python3
"""Policy steps per second of the batched torch world on this CPU, without any network.

One policy step = one 60 Hz action for every environment with all its physics (two 120 Hz ball and
contact steps, eight 480 Hz arm servo steps, forward kinematics, referee). Two figures per N:
  world  BatchedWorld.step with joint targets that change every step (a random walk around home),
         plus the resets of decided rallies with new balls from the vectorised sampler;
  env    TableTennisEnv.step (the world plus observations with noise and delays, rewards, domain
         randomisation, resets): what PPO's rollout calls.
Run by `make bench`; alone: `python3 benchmarks/30_batched_world.py` with ros2_ws/install/setup.bash sourced.
"""

from __future__ import annotations

import os
import sys
import time

import torch

SIZES = (1024, 4096)
WARMUP_STEPS = 20
MEASURED_STEPS = 120
THREADS = 2


def world_rate(num_envs: int, compile: bool = False) -> tuple[float, int, float]:
    """Policy steps per second of BatchedWorld (with resets), rallies decided, seconds to the first step."""
    from stylepong_sim.batched import batched_launcher, batched_world

    started = time.perf_counter()
    world = batched_world.BatchedWorld(num_envs, compile=compile)
    sampler = batched_launcher.IncomingBallSampler(seed=0, batch=max(4096, 2 * num_envs))
    ids = torch.arange(num_envs)
    position, velocity, _ = sampler.sample(num_envs)
    world.reset_envs(ids, world.q_rad.clone(), position, velocity)
    home = world.q_rad.clone()
    generator = torch.Generator().manual_seed(0)
    target = home.clone()
    decided = 0

    def one_step() -> int:
        with batched_world.torch_threads(1):  # as the task runs it: see batched_world.torch_threads
            return reset_decided(world.step(next_target()))

    def next_target() -> torch.Tensor:
        nonlocal target
        target = (target + 0.1 * torch.randn(target.shape, generator=generator)).clamp(home - 1.0, home + 1.0)
        return target

    def reset_decided(events) -> int:
        done = torch.nonzero(events.decided).squeeze(1)
        if done.numel():
            p, v, _ = sampler.sample(int(done.numel()))
            world.reset_envs(done, home[:, done], p, v)
        return int(done.numel())

    one_step()
    first_step_s = time.perf_counter() - started
    for _ in range(WARMUP_STEPS - 1):
        one_step()
    start = time.perf_counter()
    for _ in range(MEASURED_STEPS):
        decided += one_step()
    return num_envs * MEASURED_STEPS / (time.perf_counter() - start), decided, first_step_s


def env_rate(num_envs: int) -> float:
    from stylepong_policy.training import task

    env = task.make_env(task.TaskConfig(num_envs=num_envs), 'cpu', 0)
    env.reset()
    generator = torch.Generator().manual_seed(0)
    for _ in range(WARMUP_STEPS):
        env.step(torch.randn(num_envs, env.num_actions, generator=generator))
    actions = [torch.randn(num_envs, env.num_actions, generator=generator) for _ in range(MEASURED_STEPS)]
    start = time.perf_counter()
    for a in actions:
        env.step(a)
    return num_envs * MEASURED_STEPS / (time.perf_counter() - start)


def main() -> int:
    torch.set_num_threads(THREADS)
    load_before = os.getloadavg()[0]
    rows = []
    for n in SIZES:
        world, decided, _ = world_rate(n)
        compiled, _, compile_s = world_rate(n, compile=True)
        rows.append((n, world, compiled, compile_s, env_rate(n), decided))
    print('## Batched world: policy steps per second (no network)\n')
    print(
        f'`benchmarks/30_batched_world.py`: `stylepong_sim.batched.batched_world.BatchedWorld` on the CPU (torch '
        f'{torch.__version__}, float32; the caller has {THREADS} threads, the world steps with 1: see '
        f'`batched_world.torch_threads`), 60 Hz policy steps each with 2 physics steps at '
        f'120 Hz and 8 arm servo steps at 480 Hz; {WARMUP_STEPS} warm-up steps, then {MEASURED_STEPS} '
        f'timed. "world": the world with changing joint targets and the resets of decided rallies (new balls '
        f'from the vectorised sampler); "env": `stylepong_policy.training.task.TableTennisEnv.step` with random '
        f'actions (observations, noise, delays, rewards, domain randomisation, resets). "torch.compile": '
        f'`BatchedWorld(compile=True)` (TaskConfig.compile_world), the same physics fused by inductor '
        f'(agrees with eager to float32 rounding). Target: >= 100,000 policy steps/s at N = 4096 (eager). '
        f'Load average before the run: {load_before:.1f} (other work on the '
        f'2 cores slows every figure).\n'
    )
    print(
        '| N | world steps/s (eager) | world steps/s (torch.compile) | env steps/s (eager) | '
        'rallies decided in the eager world run |'
    )
    print('|---|---|---|---|---|')
    for n, world, compiled, compile_s, env, decided in rows:
        print(
            f'| {n} | {world:,.0f} | {compiled:,.0f} (first step after {compile_s:.0f} s of compilation) | '
            f'{env:,.0f} | {decided} |'
        )
    return 0


if __name__ == '__main__':
    sys.exit(main())
