#!/usr/bin/env python3
"""drag_teach: compute time per control cycle, and the rate it achieves at 500 Hz against ur5_sim.

1. The controller alone (no ROS): one joint state, one sensor wrench and one control cycle, repeated,
   with a push that changes every cycle (a person's hand), timed with perf_counter.
2. The node: `ros2 run stylepong_sim ur5_sim` and `ros2 run stylepong_fdcc drag_teach` (defaults:
   500 Hz, wall clock) for DURATION_S; drag_teach reports on Ctrl-C what it measured itself: cycles,
   achieved rate, missed ticks (periods without a cycle) and compute time per cycle (its timer
   callback: controller plus publishing).
3. Side by side: the same run with the drag_teach of OLD_COMMIT (its stylepong_fdcc and
   stylepong_description sources from git, first on PYTHONPATH, against today's ur5_sim), alternating
   with today's, PAIRS times each: this shared machine's load changes by the minute, so only runs
   made together compare.
Prints one Markdown section for BENCHMARKS.md (`make bench`).
"""

import os
import pathlib
import re
import subprocess
import sys
import tempfile
import time

import numpy as np

from stylepong_common.node_process import isolated_ros_env, start_logged, stop_group

ROOT = pathlib.Path(__file__).resolve().parent.parent
DURATION_S = 20.0
CYCLES = 20000
OLD_COMMIT = '9dcd180'  # the code whose drag_teach missed 0.79 % of its ticks (BENCHMARKS.md of that commit)
PAIRS = 3
STATS = re.compile(r'(\d+) cycles in .*? (\d+) missed, compute mean (\d+) us, p99 (\d+) us')


def controller_cycles() -> np.ndarray:
    from stylepong_description import robot_model
    from stylepong_fdcc.drag_teach_controller import DragTeachController
    from stylepong_fdcc.fdcc_config import FdccConfig
    from stylepong_fdcc.wrench_conditioning import gravity_wrench_on_tool, tool_load_from_model
    from stylepong_sim.world_spec import HOME_JOINT_POSITIONS_RAD

    controller = DragTeachController(FdccConfig())
    model = robot_model.pinocchio_model()
    data = model.createData()
    load = tool_load_from_model(model)
    q = np.array(HOME_JOINT_POSITIONS_RAD)
    import pinocchio as pin

    pin.framesForwardKinematics(model, data, q)
    rotation = data.oMf[model.getFrameId(robot_model.TOOL_FRAME)].rotation
    weight = gravity_wrench_on_tool(load, rotation, np.array(model.gravity.linear))
    t = 0.0
    for _ in range(200):  # start-up and tare, not timed
        controller.on_joint_positions(q, t)
        controller.on_wrench(weight, t)
        controller.tick(t)
        t += 0.002
    times = np.empty(CYCLES)
    for k in range(CYCLES):
        push = np.array([8.0 * np.sin(k * 0.004), 6.0 * np.cos(k * 0.003), 0.0])
        wrench = weight + np.concatenate([rotation.T @ push, np.zeros(3)])
        started = time.perf_counter()
        controller.on_joint_positions(q, t)
        controller.on_wrench(wrench, t)
        result = controller.tick(t)
        times[k] = time.perf_counter() - started
        q = result.command  # a perfect servo
        t += 0.002
    return times


def old_sources() -> pathlib.Path | None:
    """OLD_COMMIT's stylepong_fdcc and stylepong_description packages, extracted; None if the clone lacks it."""
    target = pathlib.Path(tempfile.mkdtemp(prefix='bench_drag_teach_old_'))
    archive = subprocess.run(
        ['git', 'archive', OLD_COMMIT, 'ros2_ws/src/stylepong_fdcc', 'ros2_ws/src/stylepong_description'],
        cwd=ROOT,
        capture_output=True,
    )
    if archive.returncode != 0:
        return None
    subprocess.run(['tar', '-x', '-C', str(target)], input=archive.stdout, check=True)
    return target / 'ros2_ws' / 'src'


def node_run(old_src: pathlib.Path | None = None) -> tuple[str, tuple[float, float, float]]:
    """drag_teach (today's, or the one in old_src) against ur5_sim; its statistics line and the load."""
    env = isolated_ros_env()
    drag_command = ['ros2', 'run', 'stylepong_fdcc', 'drag_teach']
    if old_src is not None:
        env['PYTHONPATH'] = os.pathsep.join(
            [str(old_src / 'stylepong_fdcc'), str(old_src / 'stylepong_description'), env.get('PYTHONPATH', '')]
        )
        drag_command = [sys.executable, '-m', 'stylepong_fdcc.drag_teach_node']
    logs = pathlib.Path(tempfile.mkdtemp(prefix='bench_drag_teach_'))
    sim = start_logged(['ros2', 'run', 'stylepong_sim', 'ur5_sim'], env, logs / 'ur5_sim.log')
    drag = start_logged(drag_command, env, logs / 'drag_teach.log')
    try:
        deadline = time.monotonic() + 60.0
        while 'running' not in (logs / 'drag_teach.log').read_text():
            if time.monotonic() > deadline or drag.poll() is not None:
                raise RuntimeError('drag_teach did not start:\n' + (logs / 'drag_teach.log').read_text())
            time.sleep(0.2)
        time.sleep(DURATION_S)
    finally:
        for process in (drag, sim):
            stop_group(process, timeout_s=10.0)
    stats = re.search(r'\d+ cycles in .*?rejected', (logs / 'drag_teach.log').read_text())
    if not stats:
        raise RuntimeError('drag_teach printed no statistics:\n' + (logs / 'drag_teach.log').read_text()[-2000:])
    return stats.group(0), os.getloadavg()  # the load is read while the nodes just stopped


def main() -> int:
    times_us = controller_cycles() * 1e6
    stats, load = node_run()
    print('## drag_teach: compute time per cycle, achieved rate, missed ticks at 500 Hz\n')
    print(
        '`python3 benchmarks/40_drag_teach.py`. (1) The FDCC controller alone (`DragTeachController`, '
        f'virtual dynamics model, all safety stages), {CYCLES} cycles of joint state + sensor wrench + '
        'control step with a changing push. (2) `ros2 run stylepong_fdcc drag_teach` (defaults: 500 Hz, '
        f'wall clock) against `ros2 run stylepong_sim ur5_sim` for {DURATION_S:.0f} s from start-up; '
        "the node's own count at Ctrl-C (compute = its timer callback, controller and publishing; a "
        'missed tick is a 2 ms period without a cycle).\n'
    )
    print('| what | mean | p99 | max |')
    print('|---|---|---|---|')
    print(
        f'| controller cycle, no ROS | {times_us.mean():.0f} us | {np.percentile(times_us, 99):.0f} us | '
        f'{times_us.max():.0f} us |'
    )
    print(f'\nNode against ur5_sim: {stats}.\n')
    print(
        f'Load average of the machine at the end: {load[0]:.2f} (1 min), {load[1]:.2f} (5 min) on '
        f'{os.cpu_count()} cores: other work on this shared machine takes cycles from the node, which '
        'shows as missed ticks.'
    )
    print_side_by_side(old_sources())
    return 0


def print_side_by_side(old_src: pathlib.Path | None) -> None:
    """Today's drag_teach and OLD_COMMIT's, alternating, PAIRS runs each, as a Markdown table."""
    print(f'\n### Side by side with the drag_teach of commit {OLD_COMMIT}\n')
    if old_src is None:
        print(f'Not measured: commit {OLD_COMMIT} is not in this clone.')
        return
    print(f'{PAIRS} runs of each, alternating (old first), {DURATION_S:.0f} s each, the same ur5_sim:\n')
    print('| code | run | cycles | missed ticks | missed % | compute mean | compute p99 | load (1 min) |')
    print('|---|---|---|---|---|---|---|---|')
    for run in range(1, PAIRS + 1):
        for name, source in ((f'old ({OLD_COMMIT})', old_src), ('today', None)):
            stats, load = node_run(source)
            cycles, missed, mean_us, p99_us = (int(x) for x in STATS.search(stats).groups())
            print(
                f'| {name} | {run} | {cycles} | {missed} | {100.0 * missed / (cycles + missed):.2f} % | '
                f'{mean_us} us | {p99_us} us | {load[0]:.2f} |',
                flush=True,
            )


if __name__ == '__main__':
    sys.exit(main())
