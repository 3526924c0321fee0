#!/usr/bin/env python3
"""learn_style's wall time per stage and its training throughput, end to end on this machine.

Runs `ros2 run stylepong_policy learn_style ros2_ws/bags --out TMP --minutes M` (the shipped clips, the
recipe as shipped, M = BENCH_LEARN_STYLE_MINUTES, default 6: every stage runs, the training for all but
a quarter of M) in a subprocess and reads the run's record (learn_style.json); prints one Markdown
section for BENCHMARKS.md. With the default 60 minutes the training stage gets 51 of them and the other
stages take what they take here.
"""
from __future__ import annotations

import json
import os
import pathlib
import subprocess
import sys
import tempfile
import time

MINUTES = float(os.environ.get('BENCH_LEARN_STYLE_MINUTES', 6))
DEVICE = os.environ.get('BENCH_LEARN_STYLE_DEVICE', 'cpu')
ROOT = pathlib.Path(__file__).resolve().parent.parent


def main() -> int:
    with tempfile.TemporaryDirectory() as tmp:
        run = pathlib.Path(tmp) / 'run'
        command = [sys.executable, '-m', 'stylepong_policy.learn_style', str(ROOT / 'ros2_ws' / 'bags'), '--out',
                   str(run), '--minutes', f'{MINUTES:g}', '--device', DEVICE]
        load_before = os.getloadavg()[0]
        started = time.perf_counter()
        result = subprocess.run(command, capture_output=True, text=True)
        wall_s = time.perf_counter() - started
        if result.returncode != 0:
            print(result.stdout[-2000:] + result.stderr[-2000:], file=sys.stderr)
            return 1
        state = json.loads((run / 'learn_style.json').read_text())
    stages = state['stages']
    train = stages['train']
    print('## learn_style: wall time per stage\n')
    print(f'`learn_style ros2_ws/bags --out RUN --minutes {MINUTES:g} --device {DEVICE}` (the shipped clips, '
          f'config/amp.yaml as shipped), one run, {wall_s / 60.0:.1f} min from start to report; load average '
          f'{load_before:.1f} before it and {os.getloadavg()[0]:.1f} after (2 = both cores busy: a loaded machine '
          'gives a training stage fewer samples in its budget and the other stages longer):\n')
    print('| stage | wall time (s) |')
    print('|---|---|')
    for name, record in stages.items():
        print(f'| {name} | {record["wall_time_s"]:.1f} |')
    print(f'\nTraining: {train["iterations"]} iterations, {train["samples"]} samples in '
          f'{train["training_time_s"]:.0f} s of training, **{train["samples_per_s"]:.0f} samples/s** (the '
          'world, PPO, the discriminator and the pose and stroke priors). With the default --minutes 60 the '
          'training stage gets 51 minutes; the stages after it take about what they take here.')
    return 0


if __name__ == '__main__':
    sys.exit(main())
