#!/usr/bin/env python3
"""build_dataset throughput in JointState messages per second (target: >= 30,000 msg/s on this machine;
docs/ACCEPTANCE.md).

Times the whole tool in-process (`stylepong_policy.training.build_dataset.run`: find the bag, read and decode
every JointState, check counts, resample to 60 Hz, trim, augment x2/x3/x5, write the .npz) on bags
written as StylePong's recorder writes them (rosbags, 500 Hz, six joints), and on the real UR3e recording
when ../shared/interop-bags is there. For scale it also times rosbags' own read + deserialize of the
same bag. Prints a Markdown section for BENCHMARKS.md.
"""

from __future__ import annotations

import contextlib
import io
import pathlib
import statistics
import subprocess
import sys
import tempfile
import time

import numpy as np

ROOT = pathlib.Path(__file__).resolve().parent.parent

from stylepong_policy.training.build_dataset import run  # noqa: E402
from stylepong_recording.joint_state_bags import jazzy_typestore, write_recorder_bag  # noqa: E402

TARGET_MSG_S = 30_000
RATE_HZ = 500.0
DURATION_S = 120.0  # 60,001 messages: two minutes of demonstrations at the driver's rate
REPEATS = 3
TOOLPATH = ROOT.parent / 'shared' / 'interop-bags' / 'ur3e-hw-sqlite3-v5-toolpath'


def swinging(t_s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Every joint swinging 0.6 rad at 0.4 Hz, phases staggered: continuous motion for the whole bag."""
    phase = np.arange(6) * 0.7
    omega = 2 * np.pi * 0.4
    q = np.array([0.0, -1.6, 1.5, -1.2, -1.6, 0.3]) + 0.6 * np.sin(omega * t_s[:, None] + phase)
    qd = 0.6 * omega * np.cos(omega * t_s[:, None] + phase)
    return q, qd


def time_build(bag: pathlib.Path, out: pathlib.Path) -> list[float]:
    seconds = []
    for _ in range(REPEATS):
        start = time.perf_counter()
        with contextlib.redirect_stdout(io.StringIO()):
            code = run([str(bag), '-o', str(out)])
        seconds.append(time.perf_counter() - start)
        if code != 0:
            raise RuntimeError(f'build_dataset exited {code} on {bag}')
    return seconds


def time_rosbags_deserialize(bag: pathlib.Path) -> tuple[int, float]:
    from rosbags.highlevel import AnyReader

    start = time.perf_counter()
    count = 0
    with AnyReader([bag], default_typestore=jazzy_typestore()) as reader:
        for connection, _t, raw in reader.messages(reader.connections):
            reader.deserialize(raw, connection.msgtype)
            count += 1
    return count, time.perf_counter() - start


def main() -> int:
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        tmp = pathlib.Path(tmp)
        bags = {}
        for storage in ('mcap', 'sqlite3'):
            bag = tmp / f'forward_20251121_1000{len(bags):02d}_000'
            count = write_recorder_bag(bag, swinging, DURATION_S, rate_hz=RATE_HZ, storage=storage)
            bags[storage] = (bag, count)
        if TOOLPATH.is_dir():
            bags['sqlite3, real UR3e (toolpath)'] = (TOOLPATH, 3436)
        for name, (bag, count) in bags.items():
            seconds = time_build(bag, tmp / 'out.npz')
            rows.append((name, count, min(seconds), statistics.median(seconds)))
        baseline_count, baseline_s = time_rosbags_deserialize(bags['mcap'][0])
        cli_start = time.perf_counter()
        cli = subprocess.run(
            ['ros2', 'run', 'stylepong_policy', 'build_dataset', str(bags['mcap'][0]), '-o', str(tmp / 'cli.npz')],
            capture_output=True,
            text=True,
        )
        cli_s = time.perf_counter() - cli_start

    main_rate = min(count / median for name, count, _b, median in rows if not name.startswith('sqlite3, real'))
    print('## build_dataset throughput (JointState messages/s)\n')
    print(
        f'`benchmarks/20_build_dataset_throughput.py`: the whole tool, in-process (`build_dataset.run`: read, '
        f'decode, count check, 60 Hz resampling, idle trim, x2/x3/x5 augmentation, .npz written), best and '
        f'median of {REPEATS} runs, on bags written like the recorder writes them (rosbags, {RATE_HZ:.0f} Hz '
        f'/joint_states, six joints, {DURATION_S:.0f} s). Target: >= {TARGET_MSG_S:,} msg/s.\n'
    )
    print('| bag | messages | best (s) | msg/s (best) | msg/s (median) |')
    print('|---|---:|---:|---:|---:|')
    for name, count, best, median in rows:
        print(f'| {name} | {count:,} | {best:.3f} | {count / best:,.0f} | {count / median:,.0f} |')
    print()
    print(
        f'- Slowest synthetic storage: {main_rate:,.0f} msg/s: '
        f'{"meets" if main_rate >= TARGET_MSG_S else "MISSES"} the {TARGET_MSG_S:,} msg/s target.'
    )
    print(
        f'- For scale: rosbags AnyReader + deserialize of the same mcap bag alone: '
        f'{baseline_count / baseline_s:,.0f} msg/s ({baseline_count:,} messages in {baseline_s:.2f} s).'
    )
    print(
        f'- `ros2 run stylepong_policy build_dataset <mcap bag> -o x.npz` wall time, interpreter start '
        f'included: {cli_s:.2f} s (exit {cli.returncode}).'
    )
    return 0


if __name__ == '__main__':
    sys.exit(main())
