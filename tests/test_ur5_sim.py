"""System tests of `ros2 run stylepong_sim ur5_sim` with its defaults, through its topics and services only.

One node serves the whole module (it starts in a few seconds; each test resets what it needs). These are
the ur5_sim checks of docs/ACCEPTANCE.md, except the real_time_factor 0 one
(test_ur5_sim_fast.py).
"""

import math
import signal

import numpy as np
import pinocchio as pin
import pytest

from stylepong_common.node_process import NodeProcess
from stylepong_description import robot_model
from stylepong_msgs.msg import RallyEvent
from stylepong_sim import world_spec
from stylepong_sim.testing.ur5_sim_probe import Ur5SimProbe, stamp_s

HOME = np.array(world_spec.HOME_JOINT_POSITIONS_RAD)
PARKED = HOME + np.array([math.pi, 0.0, 0.0, 0.0, 0.0, 0.0])  # turned away from the table


@pytest.fixture(scope='module')
def sim(module_ros_domain):
    node = NodeProcess('stylepong_sim', 'ur5_sim').start()
    probe = Ur5SimProbe()
    try:
        assert probe.wait_for_sim(60.0), f'ur5_sim did not come up:\n{node.output()}'
        yield node, probe
    finally:
        probe.close()
        node.stop()


def _move_and_settle(probe: Ur5SimProbe, target, timeout_s: float = 10.0) -> None:
    probe.command(target)
    assert probe.spin_until(lambda: np.abs(probe.latest_joint_positions() - target).max() < 0.002, timeout_s)


def test_joint_states_and_wrench_at_500_hz_and_a_clock(sim):
    node, probe = sim
    probe.spin_for(0.5)
    start, n_joint, n_wrench, n_clock = (
        probe.joint_states[-1].received_s,
        len(probe.joint_states),
        len(probe.wrenches),
        len(probe.clock),
    )
    probe.spin_for(4.0)
    window_s = probe.joint_states[-1].received_s - start
    joint_rate_hz = (len(probe.joint_states) - n_joint) / window_s
    wrench_rate_hz = (len(probe.wrenches) - n_wrench) / window_s
    print(f'/joint_states {joint_rate_hz:.0f} Hz, wrench {wrench_rate_hz:.0f} Hz over {window_s:.1f} s')
    assert joint_rate_hz >= 450.0, joint_rate_hz
    assert wrench_rate_hz >= 450.0, wrench_rate_hz
    assert probe.joint_names == list(robot_model.JOINT_NAMES)
    positions, velocities, efforts = probe.joint_states[-1].values
    assert len(positions) == len(velocities) == len(efforts) == 6
    assert probe.wrench_frames == {'tool0'}
    # Stamps on the simulated clock, 2 ms apart; /clock runs and matches them.
    stamps = np.array([s.stamp_s for s in probe.joint_states[-200:]])
    np.testing.assert_allclose(np.diff(stamps), 0.002, atol=1e-6)
    assert len(probe.clock) - n_clock > 1000
    assert abs(probe.clock[-1].stamp_s - probe.joint_states[-1].stamp_s) < 0.2
    assert node.running()


def test_a_03_rad_step_is_tracked_and_bad_commands_are_held_off(sim):
    node, probe = sim
    probe.reset()
    probe.spin_for(0.3)
    target = HOME + np.array([0.3, -0.3, 0.3, 0.3, -0.3, 0.3])
    commanded_at_s = probe.joint_states[-1].stamp_s
    probe.command(target)
    assert probe.spin_until(lambda: probe.joint_states[-1].stamp_s > commanded_at_s + 2.5, 15.0)
    after = [s for s in probe.joint_states if s.stamp_s > commanded_at_s]
    errors = np.array([np.abs(s.values[0] - target).max() for s in after])
    settled = np.flatnonzero(errors >= 0.01)
    tracked_at_s = after[settled[-1] + 1].stamp_s if settled.size else after[0].stamp_s
    print(f'0.3 rad step tracked to < 0.01 rad after {tracked_at_s - commanded_at_s:.3f} s (sim)')
    assert tracked_at_s - commanded_at_s <= 2.0

    count = len(probe.joint_states)
    probe.command([math.nan] * 6)
    probe.command([0.1] * 5)
    probe.command(list(target[:5]) + [math.inf])
    probe.command(list(target[:5]) + [100.0])  # outside wrist_3's limits
    probe.spin_for(1.5)
    held = probe.joint_states[count:]
    assert len(held) > 300
    held_error = max(np.abs(s.values[0] - target).max() for s in held)
    print(f'after NaN/inf/short/out-of-limit commands: largest error {held_error:.2e} rad over {len(held)} samples')
    assert held_error < 0.01
    assert node.running()
    assert 'command rejected' in node.output()


def test_a_30_cm_drop_rebounds_to_an_ittf_height(sim):
    _, probe = sim
    probe.reset()
    first = len(probe.balls)
    response = probe.launch(randomize=False, position=_point(-0.5, 0.0, world_spec.TABLE_HEIGHT_M + 0.305))
    assert response.success, response.message
    assert probe.spin_until(lambda: _rebound_apex(probe.balls[first:]) is not None, 10.0)
    apex_m = _rebound_apex(probe.balls[first:])[2] - world_spec.TABLE_HEIGHT_M
    print(f'30.5 cm drop: rebound apex {apex_m:.4f} m above the surface')
    assert 0.215 <= apex_m <= 0.265
    assert probe.ball_frames == {'world'}


def _point(x, y, z):
    from geometry_msgs.msg import Point

    return Point(x=float(x), y=float(y), z=float(z))


def _rebound_apex(samples):
    """Ball centre at the top of the first rebound: after the first fall-to-rise turn (the bounce; a serve
    may rise first), the first sample that falls again."""
    fell = bounced = False
    for sample in samples:
        vz = sample.values[1][2]
        if vz < 0.0 and not bounced:
            fell = True
        elif vz > 0.0 and fell:
            bounced = True
        elif vz <= 0.0 and bounced:
            return sample.values[0]
    return None


def _events_of(probe: Ur5SimProbe, ball_id: int) -> list:
    return [e for e in probe.events if e.ball_id == ball_id]


def _first_bounce_and_apex(probe: Ur5SimProbe, ball_id: int):
    """The ball's first table bounce (event) and its centre at the top of the rebound (first /ball/state
    sample stamped after the bounce that no longer rises), or None while not yet seen."""
    bounces = [
        e for e in _events_of(probe, ball_id) if e.type in (RallyEvent.BOUNCE_OWN_SIDE, RallyEvent.BOUNCE_OPPONENT_SIDE)
    ]
    if not bounces:
        return None
    bounce_s = stamp_s(bounces[0].header.stamp)
    for sample in probe.balls:
        if sample.stamp_s > bounce_s and sample.values[1][2] <= 0.0:
            return bounces[0], sample.values[0]
    return None


@pytest.mark.slow  # over 20 s on the 2-core machine: .ci/run runs it, `make test` skips it
def test_randomized_balls_need_every_stroke(sim):
    _, probe = sim
    probe.reset()
    _move_and_settle(probe, PARKED)  # the arm out of the balls' way: the distribution alone is measured
    speeds, lateral_m = [], []
    for seed in range(100, 116):
        response = probe.launch(randomize=True, seed=seed, speed_min=0.0, speed_max=0.0)
        assert response.success, response.message
        speeds.append(math.sqrt(response.velocity.x**2 + response.velocity.y**2 + response.velocity.z**2))
        assert probe.spin_until(lambda: _first_bounce_and_apex(probe, response.ball_id) is not None, 10.0), (
            seed,
            [(e.type, e.reason) for e in _events_of(probe, response.ball_id)],
        )
        bounce, apex = _first_bounce_and_apex(probe, response.ball_id)
        assert bounce.type == RallyEvent.BOUNCE_OWN_SIDE, seed
        assert -world_spec.HALF_LENGTH_M <= bounce.position.x < 0.0, seed
        assert abs(bounce.position.y) <= world_spec.HALF_WIDTH_M, seed
        lateral_m.append(apex[1])
    print(
        f'{len(speeds)} balls: speeds {min(speeds):.2f}-{max(speeds):.2f} m/s, apex y {min(lateral_m):.2f} to '
        f'{max(lateral_m):.2f} m (span {max(lateral_m) - min(lateral_m):.2f} m)'
    )
    assert min(speeds) >= 4.0 and max(speeds) <= 6.6
    assert max(speeds) - min(speeds) >= 2.0
    assert max(lateral_m) - min(lateral_m) >= 0.8


def test_seed_7_against_a_motionless_arm_is_no_return(sim):
    _, probe = sim
    probe.reset()
    probe.spin_for(0.3)
    response = probe.launch(randomize=True, seed=7)
    assert response.success, response.message
    assert probe.spin_until(
        lambda: any(e.type == RallyEvent.RALLY_END for e in _events_of(probe, response.ball_id)), 8.0
    )
    events = _events_of(probe, response.ball_id)
    assert [e.type for e in events] == [RallyEvent.LAUNCHED, RallyEvent.BOUNCE_OWN_SIDE, RallyEvent.RALLY_END]
    assert not events[-1].success and events[-1].reason
    duration_s = stamp_s(events[-1].header.stamp) - stamp_s(events[0].header.stamp)
    print(f'seed 7: RALLY_END ({events[-1].reason}) {duration_s:.3f} s after LAUNCHED')
    assert duration_s <= 3.0


def _tool_rotation_in_world(q) -> np.ndarray:
    model = robot_model.pinocchio_model()
    data = model.createData()
    pin.framesForwardKinematics(model, data, np.asarray(q))
    base_rotation, _ = world_spec.robot_base_pose()
    return base_rotation @ data.oMf[model.getFrameId(robot_model.TOOL_FRAME)].rotation


def _mean_force(samples) -> np.ndarray:
    return np.mean([s.values[0] for s in samples], axis=0)


def test_a_10_n_push_in_world_x_shows_on_the_wrist_sensor_in_tool0(sim):
    _, probe = sim
    probe.reset()
    probe.spin_for(0.5)
    count = len(probe.wrenches)
    probe.spin_for(0.3)
    baseline = _mean_force(probe.wrenches[count:])
    q_before = probe.latest_joint_positions()
    expected = _tool_rotation_in_world(q_before).T @ np.array([10.0, 0.0, 0.0])

    pushing_from = len(probe.wrenches)
    joints_from = len(probe.joint_states)
    for _ in range(60):  # a hand pushing for 0.6 s, refreshed well inside the 0.1 s timeout
        probe.push([10.0, 0.0, 0.0], frame='world')
        probe.spin_for(0.01)
    pushed = _mean_force(probe.wrenches[pushing_from:][-100:])
    change = pushed - baseline
    print(
        f'10 N world +x: F/T change {np.round(change, 3)} N, expected {np.round(expected, 3)} N, '
        f'error {np.linalg.norm(change - expected):.3f} N'
    )
    assert np.linalg.norm(change - expected) <= 0.05 * 10.0, (change, expected)
    deflection = max(np.abs(s.values[0] - q_before).max() for s in probe.joint_states[joints_from:])
    assert deflection < 0.01  # the arm holds its pose

    probe.spin_for(0.4)  # the hand let go: after 0.1 s its wrench is dropped
    released = _mean_force(probe.wrenches[-50:])
    assert np.linalg.norm(released - baseline) < 0.2


def test_ctrl_c_stops_the_node_cleanly(sim):
    node, probe = sim
    node.signal(signal.SIGINT)
    node.process.wait(10.0)
    assert node.process.returncode == 0
    assert 'Traceback' not in node.output() and 'FATAL' not in node.output()
