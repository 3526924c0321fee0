#!/usr/bin/env python3
"""The sim2sim test through ROS: the deployed style actor in ur5_sim with realistic sensing.

A full run (200 balls at real time, about half an hour on this machine) is too long for `make bench`,
so by default this section reports results/sim2sim_ros.json, which `tools/sim2sim.sh` wrote (the
command is printed with it); with BENCH_SIM2SIM_RUN=1 it runs `tools/sim2sim.sh` first and reports
the fresh file. Either way the figures come from the file, never typed.
"""

from __future__ import annotations

import json
import os
import pathlib
import subprocess
import sys

ROOT = pathlib.Path(__file__).resolve().parent.parent
RESULT = ROOT / 'results' / 'sim2sim_ros.json'
RANDOMISED = ROOT / 'results' / 'sim2sim_batched_randomized.json'
COMMAND = [
    'tools/sim2sim.sh',
    '--actor',
    'ros2_ws/src/stylepong_policy/models/amp_actor.pt',
    '--seeds',
    '10',
    '--first-seed',
    '1000',
    '--balls',
    '20',
    '--json',
    'results/sim2sim_ros.json',
]


def percentile_text(stats: dict, key: str) -> str:
    value = stats.get(key)
    return 'n/a' if value is None else f'{value:.2f}'


def main() -> int:
    if os.environ.get('BENCH_SIM2SIM_RUN') == '1':
        subprocess.run(COMMAND, cwd=ROOT, check=True, stdout=subprocess.DEVNULL)
    print('## Sim2sim through ROS (ur5_sim, realistic sensing)\n')
    if not RESULT.is_file():
        print(f'No `{RESULT.relative_to(ROOT)}` yet: run `{" ".join(COMMAND)}`.')
        return 0
    r = json.loads(RESULT.read_text())
    status = r.get('player_status') or {}
    print(
        f'`{" ".join(COMMAND)}` (from `results/sim2sim_ros.json`; `BENCH_SIM2SIM_RUN=1 make bench` re-runs it): '
        f'{r.get("world", "ur5_sim through ROS")}. Actor `{r.get("actor")}`, seeds {r["seeds"][0]}-{r["seeds"][-1]}, '
        f'{r["balls"] // len(r["seeds"])} balls each.\n'
    )
    print('| setting | balls | success rate | std over seeds | hit rate | failures |')
    print('|---|---|---|---|---|---|')
    print(
        f'| through ROS, ur5_sim + realistic sensing | {r["balls"]} | {r["success_rate"]:.3f} | '
        f'{r.get("success_rate_std", 0.0):.3f} | {r["hit_rate"]:.3f} | {r["failures"]} |'
    )
    if RANDOMISED.is_file():
        b = json.loads(RANDOMISED.read_text())
        print(
            f'| batched world, training randomisation (`evaluate --randomize`) | {b["balls"]} | '
            f'{b["success_rate"]:.3f} | {b["success_rate_std"]:.3f} | {b["hit_rate"]:.3f} | {b["failures"]} |'
        )
    latency = status.get('latency_ms') or {}
    period = status.get('period_ms') or {}
    if latency or period:
        print(
            f'\nThe player during that run ({status.get("backend", "?")} backend): ball-stamp-to-command latency '
            f'p50 {percentile_text(latency, "p50")} ms, p99 {percentile_text(latency, "p99")} ms (the stamp is '
            f'the camera exposure, so this includes the sensing latency of realistic_sensing.yaml); period '
            f"jitter p99 {percentile_text(period, 'jitter_p99')} ms on the cell's clock."
        )
    return 0


if __name__ == '__main__':
    sys.exit(main())
