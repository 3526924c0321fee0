#!/usr/bin/env python3
"""player: period jitter, ball-message-to-command latency, inference time per backend and CPU share.

1. The actor alone (no ROS): one observation per call, ONNX (onnxruntime, 1 thread) and TorchScript
   (torch, 1 thread), and one whole Player policy step (observation, ONNX actor, decoding, limiter).
2. The node alone, wall clock: `ros2 run stylepong_player player` (enabled) fed by this script with
   /joint_states at 500 Hz and /ball/state at 120 Hz stamped with the wall clock, DURATION_S per backend;
   the figures are the player's own (/player/status): period between policy steps and its jitter
   (|period - 1/60 s|), latency from the ball message's header stamp to publishing the command, inference
   time, and the process's CPU share (/proc).
3. With ur5_sim and ball_estimator in the loop (nominal sensing, real_time_factor 1, the player on /clock): rally_eval
   serves RALLY_BALLS balls; the same figures, on the cell's clock (1 ms resolution).
Prints one Markdown section for BENCHMARKS.md (`make bench`).
"""

import json
import os
import pathlib
import sys
import tempfile
import time

import numpy as np

from stylepong_common.node_process import isolated_ros_env, process_cpu_s, run_rally_eval, start_logged, stop_group

ROOT = pathlib.Path(__file__).resolve().parent.parent
ACTOR = ROOT / 'ros2_ws/src/stylepong_policy/models/amp_actor.pt'  # the deployed style actor
DURATION_S = 15.0
CALLS = 3000
RALLY_BALLS = 6


def actor_alone() -> dict[str, np.ndarray]:
    from stylepong_player import player_core, spec

    rng = np.random.default_rng(0)
    obs = rng.normal(0, 1, (CALLS, 1, spec.NUM_OBS)).astype(np.float32)
    times = {}
    for backend in player_core.BACKENDS:
        actor = player_core.load_actor(ACTOR, backend)
        for k in range(200):
            actor(obs[k])
        t = np.empty(CALLS)
        for k in range(CALLS):
            started = time.perf_counter()
            actor(obs[k])
            t[k] = time.perf_counter() - started
        times[backend] = t
    core = player_core.Player(player_core.PlayerConfig(), player_core.load_actor(ACTOR, 'onnx'))
    core.set_enabled(True)
    names, home = list(spec.JOINT_NAMES), list(spec.HOME_JOINT_POSITIONS_RAD)
    steps = []
    for k in range(CALLS):
        now = 1.0 + k / 60.0
        core.on_joint_state(names, home, [0.0] * 6, now)
        core.on_ball('world', now, (-1.0, 0.1 * np.sin(k), 1.0), (-5.0, 0.0, 0.5), now)
        started = time.perf_counter()
        core.step(now)
        steps.append(time.perf_counter() - started)
    times['Player step (ONNX)'] = np.array(steps)
    return times


def node_alone(backend: str) -> tuple[dict, float]:
    """The player fed by a synthetic robot and camera on the wall clock; returns (status, CPU share)."""
    os.environ.update(isolated_ros_env())
    import rclpy
    from rclpy.executors import SingleThreadedExecutor
    from sensor_msgs.msg import JointState
    from std_msgs.msg import String

    from stylepong_msgs.msg import BallState
    from stylepong_player import spec

    logs = pathlib.Path(tempfile.mkdtemp(prefix='bench_player_'))
    player = start_logged(
        [
            'ros2',
            'run',
            'stylepong_player',
            'player',
            '--ros-args',
            '-p',
            'start_enabled:=true',
            '-p',
            f'backend:={backend}',
            '-p',
            'status_rate_hz:=1.0',
        ],
        dict(os.environ),
        logs / 'player.log',
    )
    context = rclpy.Context()
    rclpy.init(context=context)
    node = rclpy.create_node('bench_player_rig', context=context)
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(node)
    status: list[dict] = []
    node.create_subscription(String, '/player/status', lambda m: status.append(json.loads(m.data)), 10)
    joint_pub = node.create_publisher(JointState, '/joint_states', 10)
    ball_pub = node.create_publisher(BallState, '/ball/state', 10)
    joints = JointState(name=list(spec.JOINT_NAMES), position=list(spec.HOME_JOINT_POSITIONS_RAD), velocity=[0.0] * 6)
    ball = BallState()
    ball.header.frame_id = 'world'
    try:
        deadline = time.monotonic() + 60.0
        while not status:
            if time.monotonic() > deadline or player.poll() is not None:
                raise RuntimeError('player did not start:\n' + (logs / 'player.log').read_text())
            executor.spin_once(timeout_sec=0.05)
        start = time.monotonic()
        cpu_start = process_cpu_s(player.pid)
        next_joint = next_ball = start
        k = 0
        while (now := time.monotonic()) - start < DURATION_S:
            if now >= next_joint:
                next_joint += 0.002
                joints.header.stamp = node.get_clock().now().to_msg()
                joint_pub.publish(joints)
            if now >= next_ball:
                next_ball += 1.0 / 120.0
                k += 1
                ball.header.stamp = node.get_clock().now().to_msg()
                ball.position.x, ball.position.y, ball.position.z = 1.2 - (k % 240) * 0.012, 0.1, 1.0
                ball.velocity.x, ball.velocity.y, ball.velocity.z = -5.0, 0.0, 0.3
                ball_pub.publish(ball)
            executor.spin_once(timeout_sec=0.0)
            time.sleep(max(0.0, min(next_joint, next_ball) - time.monotonic()))
        cpu_share = (process_cpu_s(player.pid) - cpu_start) / (time.monotonic() - start)
        status.clear()
        while not status:
            executor.spin_once(timeout_sec=0.1)
        return status[-1], cpu_share
    finally:
        executor.shutdown()
        node.destroy_node()
        rclpy.shutdown(context=context)
        stop_group(player)


def with_ur5_sim() -> tuple[dict, float, dict]:
    env = isolated_ros_env()
    logs = pathlib.Path(tempfile.mkdtemp(prefix='bench_player_sim_'))
    sim = start_logged(
        ['ros2', 'run', 'stylepong_sim', 'ur5_sim', '--ros-args', '-p', 'max_lag_s:=0.01'], env, logs / 'ur5_sim.log'
    )
    # The cell's tracker reports positions; ball_estimator gives the player /ball/state, as on a real cell.
    estimator = start_logged(['ros2', 'run', 'stylepong_player', 'ball_estimator'], env, logs / 'ball_estimator.log')
    player = start_logged(
        ['ros2', 'run', 'stylepong_player', 'player', '--ros-args', '-p', 'use_sim_time:=true'],
        env,
        logs / 'player.log',
    )
    try:
        time.sleep(3.0)
        cpu_start, wall_start = process_cpu_s(player.pid), time.monotonic()
        out = logs / 'rally.json'
        run_rally_eval(env, RALLY_BALLS, 900, out).check_returncode()
        cpu_share = (process_cpu_s(player.pid) - cpu_start) / (time.monotonic() - wall_start)
        summary = json.loads(out.read_text())
        return summary['player_status'], cpu_share, summary
    finally:
        stop_group(player)
        stop_group(estimator)
        stop_group(sim)


def _row(what: str, s: dict, key: str = 'p50') -> str:
    if not s or not s.get('count'):
        return f'| {what} | - | - | - |'
    return f'| {what} | {s["p50"]:.3f} | {s["p99"]:.3f} | {s["max"]:.3f} |'


def _jitter(s: dict) -> dict:
    """|period - 1/60 s| summary in ms from a period summary (p50/p99 of the period, jitter p99 and max)."""
    return {
        'count': s.get('count', 0),
        'p50': abs(s.get('p50', 0) - 1e3 / 60.0),
        'p99': s.get('jitter_p99', 0),
        'max': s.get('jitter_max', 0),
    }


def main() -> int:
    alone = actor_alone()
    nodes = {backend: node_alone(backend) for backend in ('onnx', 'torchscript')}
    sim_status, sim_cpu, rally = with_ur5_sim()
    print('## player: period jitter, ball-to-command latency, inference time, CPU share\n')
    print(
        f'`python3 benchmarks/50_player.py`, the shipped style actor (`models/{ACTOR.name}` / `.onnx`). '
        f'(1) The actor alone: {CALLS} calls with one observation, and {CALLS} whole Player policy steps '
        '(observation, '
        'ONNX actor, decoding, limiter). (2) `ros2 run stylepong_player player` (enabled, wall clock) fed by '
        f'this script: /joint_states at 500 Hz, /ball/state at 120 Hz stamped on sending, {DURATION_S:.0f} s '
        "per backend; the figures are the node's own (/player/status): period between policy steps, jitter "
        '= |period - 16.667 ms|, latency = ball header stamp to the command published, inference = the '
        'actor call; CPU share of the player process. (3) The same with ur5_sim in the loop (nominal sensing, '
        f'real_time_factor 1, max_lag_s 0.01, player on /clock, rally_eval serving {RALLY_BALLS} balls of seed 900): '
        'periods '
        "and latency on the cell's clock (1 ms resolution).\n"
    )
    print('| actor alone, no ROS | p50 (us) | p99 (us) | max (us) |')
    print('|---|---|---|---|')
    for name, t in alone.items():
        us = t * 1e6
        print(f'| {name} | {np.percentile(us, 50):.0f} | {np.percentile(us, 99):.0f} | {us.max():.0f} |')
    print('\n| player node (ms) | p50 | p99 | max |')
    print('|---|---|---|---|')
    for backend, (s, cpu) in nodes.items():
        print(_row(f'alone, {backend}: period', s['period_wall_ms']))
        print(_row(f'alone, {backend}: period jitter', _jitter(s['period_ms'])))
        print(_row(f'alone, {backend}: ball stamp -> command', s['latency_ms']))
        print(_row(f'alone, {backend}: inference', s['inference_ms']))
    print(_row('with ur5_sim, onnx: period (cell clock)', sim_status['period_ms']))
    print(_row('with ur5_sim, onnx: period jitter (cell clock)', _jitter(sim_status['period_ms'])))
    print(_row('with ur5_sim, onnx: period (wall clock)', sim_status['period_wall_ms']))
    print(_row('with ur5_sim, onnx: ball stamp -> command (cell clock)', sim_status['latency_ms']))
    print(_row('with ur5_sim, onnx: ball message callback -> command (wall)', sim_status['receipt_latency_ms']))
    print(_row('with ur5_sim, onnx: inference', sim_status['inference_ms']))
    shares = ', '.join(f'{backend} {cpu * 100:.1f} %' for backend, (_, cpu) in nodes.items())
    print(
        f'\nCPU share of the player process (one core = 100 %): alone {shares}; with ur5_sim {sim_cpu * 100:.1f} % '
        '(it then also follows /clock at 1 kHz). Policy steps driven by a ball message / fallback steps with '
        f'ur5_sim: {sim_status["counts"].get("ball_driven_steps", 0)} / '
        f'{sim_status["counts"].get("fallback_steps", 0)}; '
        f'rally: {rally["success_rate"]:.2f} success over {rally["balls"]} balls. Load average at the end: '
        f'{os.getloadavg()[0]:.2f} on {os.cpu_count()} cores (a shared machine: other work shows in the p99s).'
    )
    return 0


if __name__ == '__main__':
    sys.exit(main())
