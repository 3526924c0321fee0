#!/usr/bin/env python3
"""learn_style's wall time per stage and its training throughput, end to end on this machine.

Runs `ros2 run stylepong_policy learn_style ros2_ws/bags --out TMP --minutes M` (the shipped clips, the
recipe as shipped, M = BENCH_LEARN_STYLE_MINUTES, default 6: every stage runs, the training for all but
a quarter of M) in a subprocess and reads the run's record (learn_style.json); prints one Markdown
section for BENCHMARKS.md. With the default 60 minutes the training stage gets 51 of them and the other
stages take what they take here. The section ends with the GPU figures read from GPU_LOG, the log of a
learn_style run on a lent GPU (this machine has none).
"""

from __future__ import annotations

import json
import os
import pathlib
import re
import subprocess
import sys
import tempfile
import time

MINUTES = float(os.environ.get('BENCH_LEARN_STYLE_MINUTES', 6))
DEVICE = os.environ.get('BENCH_LEARN_STYLE_DEVICE', 'cpu')
ROOT = pathlib.Path(__file__).resolve().parent.parent
GPU_LOG = ROOT / 'benchmarks' / 'logs' / 'learn_style_cuda_h100.log'


def gpu_paragraph(log: pathlib.Path) -> str:
    """The GPU run's training throughput, from its progress lines ('train ... | T/B s [..., it K, ...')."""
    from stylepong_policy.training import learn_style

    steps_per_env = learn_style.recipe(None)[0].ppo.num_steps_per_env
    text = log.read_text()
    envs = int(re.search(r'(\d+) envs on cuda', text).group(1))
    points = [(float(t), int(k)) for t, k in re.findall(r'train .*?\| *([\d.]+)/[\d.]+ s \[[^,\n]*, it (\d+)', text)]
    (t0, k0), (t1, k1) = points[0], points[-1]
    samples_per_iteration = steps_per_env * envs
    steady = (k1 - k0) / (t1 - t0) * samples_per_iteration
    first_iteration_s = t0 - k0 * samples_per_iteration / steady
    machine, command = (line.lstrip('# ') for line in text.splitlines()[:2])
    return (
        f'On a GPU ({machine}; {command}; not run by `make bench`, read from [its log]({log.relative_to(ROOT)})): '
        f'{k1} iterations in {t1:.0f} s of training, {k1 * samples_per_iteration / t1:.0f} samples/s overall; '
        f'the first iteration after about {first_iteration_s:.0f} s (torch.compile of the world), then '
        f'**{steady:.0f} samples/s**. At {envs} environments a world step and a minibatch are bound by kernel '
        'launches, not arithmetic, so the GPU gives the recipe little.'
    )


def main() -> int:
    with tempfile.TemporaryDirectory() as tmp:
        run = pathlib.Path(tmp) / 'run'
        command = [
            sys.executable,
            '-m',
            'stylepong_policy.training.learn_style',
            str(ROOT / 'ros2_ws' / 'bags'),
            '--out',
            str(run),
            '--minutes',
            f'{MINUTES:g}',
            '--device',
            DEVICE,
        ]
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
    print(
        f'`learn_style ros2_ws/bags --out RUN --minutes {MINUTES:g} --device {DEVICE}` (the shipped clips, '
        f'config/amp.yaml as shipped), one run, {wall_s / 60.0:.1f} min from start to report; load average '
        f'{load_before:.1f} before it and {os.getloadavg()[0]:.1f} after (2 = both cores busy: a loaded machine '
        'gives a training stage fewer samples in its budget and the other stages longer):\n'
    )
    print('| stage | wall time (s) |')
    print('|---|---|')
    for name, record in stages.items():
        print(f'| {name} | {record["wall_time_s"]:.1f} |')
    print(
        f'\nTraining: {train["iterations"]} iterations, {train["samples"]} samples in '
        f'{train["training_time_s"]:.0f} s of training, **{train["samples_per_s"]:.0f} samples/s** (the '
        'world, PPO, the discriminator and the pose and stroke priors). With the default --minutes 60 the '
        "training stage gets 51 minutes less the skill stage's (the library validated against the clips); "
        'the stages after it take about what they take here.'
    )
    if GPU_LOG.is_file():
        print('\n' + gpu_paragraph(GPU_LOG))
    return 0


if __name__ == '__main__':
    sys.exit(main())
