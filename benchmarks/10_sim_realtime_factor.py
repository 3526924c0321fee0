#!/usr/bin/env python3
"""Real-time factor of the simulated cell: the ROS-free Cell alone, and `ur5_sim` with all topics published.

Run by `make bench` (prints one Markdown section); alone: `python3 benchmarks/10_sim_realtime_factor.py`
in a shell with ros2_ws/install/setup.bash sourced.
"""

import os
import pathlib
import random
import sys
import time

ROOT = pathlib.Path(__file__).resolve().parent.parent
# A ROS domain of its own, traffic on the loopback only (as the test suite does).
os.environ['ROS_DOMAIN_ID'] = str(random.Random(os.getpid()).randint(1, 101))
os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'


from stylepong_common import markdown  # noqa: E402
from stylepong_common.node_process import NodeProcess  # noqa: E402
from stylepong_sim import world_spec  # noqa: E402
from stylepong_sim.cells.cell import Cell  # noqa: E402
from stylepong_sim.testing.ur5_sim_probe import Ur5SimProbe  # noqa: E402

NODE_WINDOW_S = 8.0


def cell_alone() -> tuple[float, float]:
    """Physics steps per second (one core, Python loop) without and with a ball in flight."""
    cell = Cell()
    cell.step(500)
    start = time.perf_counter()
    cell.step(5000)
    idle = 5000 / (time.perf_counter() - start)
    steps, elapsed = 0, 0.0
    for seed in range(5):
        launch = world_spec.incoming_ball_for_seed(seed)
        cell.launch_ball(launch.position_m, launch.velocity_m_s)
        start = time.perf_counter()
        cell.step(800)
        elapsed += time.perf_counter() - start
        steps += 800
    return idle, steps / elapsed


def process_cpu_s(pid: int) -> float:
    """User + system CPU seconds of a process and its waited-for children (from /proc)."""
    fields = pathlib.Path(f'/proc/{pid}/stat').read_text().rsplit(')', 1)[1].split()
    return sum(int(v) for v in fields[11:15]) / os.sysconf('SC_CLK_TCK')


def node_run(real_time_factor: float) -> dict:
    """ur5_sim with a probe subscribed to every topic; balls launched throughout."""
    with NodeProcess('stylepong_sim', 'ur5_sim', params={'real_time_factor': real_time_factor}) as node:
        probe = Ur5SimProbe('bench_probe')
        try:
            if not probe.wait_for_sim(60.0):
                raise RuntimeError(f'ur5_sim did not start:\n{node.output()}')
            probe.spin_for(1.0)
            pid = node.process.pid
            # `ros2 run` execs the node in this project's ros2 command; measure the python process itself.
            children = pathlib.Path(f'/proc/{pid}/task/{pid}/children')
            if children.exists() and children.read_text().split():
                pid = int(children.read_text().split()[0])
            counts = (len(probe.joint_states), len(probe.wrenches), len(probe.balls))
            clock0, cpu0, wall0 = probe.clock[-1], process_cpu_s(pid), time.monotonic()
            seed = 0
            while time.monotonic() - wall0 < NODE_WINDOW_S:
                probe.launch(randomize=True, seed=seed)
                seed += 1
                probe.spin_for(1.0)
            wall_s = time.monotonic() - wall0
            clock1, cpu1 = probe.clock[-1], process_cpu_s(pid)
            return {
                'speed': (clock1.stamp_s - clock0.stamp_s) / (clock1.received_s - clock0.received_s),
                'joint_hz': (len(probe.joint_states) - counts[0]) / wall_s,
                'wrench_hz': (len(probe.wrenches) - counts[1]) / wall_s,
                'ball_hz': (len(probe.balls) - counts[2]) / wall_s,
                'cpu': (cpu1 - cpu0) / wall_s,
                'balls': seed,
            }
        finally:
            probe.close()


def main() -> int:
    idle_steps, ball_steps = cell_alone()
    fast = node_run(0.0)
    paced = node_run(1.0)
    load = os.getloadavg()[0]
    print('## Simulated cell: real-time factor (`ur5_sim`)\n')
    print(
        'Physics step 1 ms (MuJoCo 4, implicitfast, UR5 collision meshes) plus the analytic ball, servo and '
        'referee in Python. "Cell alone": `stylepong_sim.cells.cell.Cell.step` in a loop, no ROS. "Node": '
        '`ros2 run stylepong_sim ur5_sim` with a probe process subscribed to every topic '
        '(/joint_states and the F/T wrench at 500 Hz, /clock every step, /sim/ball/ground_truth at 120 Hz, '
        '/rally/events) '
        f'and a randomized ball launched every wall second for {NODE_WINDOW_S:.0f} s. '
        "Rates are messages received by the probe per wall second; CPU is the node process's share of one core. "
        f'1-minute load average at the end: {load:.1f} (other work on the machine lowers these figures).\n'
    )
    header = ['setting', 'real-time factor achieved', '/joint_states Hz', 'wrench Hz', 'ball truth Hz', 'node CPU']
    rows = [
        ['Cell alone, no ball', f'{idle_steps / 1000:.1f}', '', '', '', '1 core'],
        ['Cell alone, ball in flight', f'{ball_steps / 1000:.1f}', '', '', '', '1 core'],
    ]
    for name, r in (
        ('Node, real_time_factor 0 (as fast as possible)', fast),
        ('Node, real_time_factor 1 (default)', paced),
    ):
        rows.append(
            [
                name,
                f'{r["speed"]:.2f}',
                f'{r["joint_hz"]:.0f}',
                f'{r["wrench_hz"]:.0f}',
                f'{r["ball_hz"]:.0f}',
                f'{100 * r["cpu"]:.0f} %',
            ]
        )
    print('\n'.join(markdown.table(header, rows)))
    print(
        '\nTargets (docs/ACCEPTANCE.md): /joint_states and wrench >= 450 Hz at '
        'real_time_factor 1; /clock >= 1.5x wall time at real_time_factor 0.'
    )
    return 0


if __name__ == '__main__':
    sys.exit(main())
