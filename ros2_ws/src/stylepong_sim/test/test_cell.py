"""The ROS-free MuJoCo cell: model, servo, F/T sensing, hand wrench, ball physics, contacts, referee wiring."""

import math

import numpy as np
import pytest

from stylepong_description import robot_model
from stylepong_sim import referee, world_spec
from stylepong_sim.cells.cell import Cell, InputError

HOME = np.array(world_spec.HOME_JOINT_POSITIONS_RAD)
# The arm turned away from the table, out of every incoming ball's way.
PARKED = HOME + np.array([math.pi, 0.0, 0.0, 0.0, 0.0, 0.0])


@pytest.fixture(scope='module')
def shared_cell() -> Cell:
    return Cell()


@pytest.fixture
def cell(shared_cell: Cell) -> Cell:
    shared_cell.reset()
    shared_cell.pop_events()
    return shared_cell


def _run_until_end(cell: Cell, max_s: float = 4.0) -> list[referee.RallyEvent]:
    events = []
    for _ in range(round(max_s / cell.dt_s)):
        cell.step(1)
        events += cell.pop_events()
        if events and events[-1].type == referee.RALLY_END:
            break
    return events


def test_the_model_is_the_one_robot_placed_by_the_world_spec(cell):
    m = cell.model
    assert m.opt.timestep <= 0.001
    assert tuple(m.joint(i).name for i in range(6)) == robot_model.JOINT_NAMES
    robot_alone = robot_model.mujoco_model()
    for body in range(1, robot_alone.nbody):
        name = robot_alone.body(body).name
        assert m.body(name).mass[0] == pytest.approx(robot_alone.body_mass[body], abs=1e-12)
    np.testing.assert_allclose(m.body(robot_model.BASE_FRAME).pos, world_spec.ROBOT_BASE_POSITION_M)
    np.testing.assert_allclose(cell.joint_positions_rad, HOME)


def test_a_03_rad_step_is_tracked_within_the_limits(cell):
    limits = robot_model.joint_limits()
    target = HOME + np.array([0.3, -0.3, 0.3, 0.3, -0.3, 0.3])
    cell.set_joint_targets(target)
    peak_speed = np.zeros(6)
    peak_servo_torque = np.zeros(6)
    for _ in range(2000):
        cell.step(1)
        peak_speed = np.maximum(peak_speed, np.abs(cell.joint_velocities_rad_s))
        peak_servo_torque = np.maximum(peak_servo_torque, np.abs(cell.data.qfrc_actuator[:6]))
    assert np.abs(cell.joint_positions_rad - target).max() < 0.01
    assert np.all(peak_speed <= limits.velocity_rad_s + 1e-9)
    assert np.all(peak_servo_torque <= limits.effort_nm + 1e-6)
    assert peak_speed.max() > 1.0  # it did move briskly, not creep


def test_bad_targets_are_rejected_and_the_last_good_one_is_kept(cell):
    good = HOME + 0.1
    cell.set_joint_targets(good)
    limits = robot_model.joint_limits()
    for bad, kind in (
        ([0.0] * 5, 'length'),
        ([0.0] * 7, 'length'),
        ([math.nan] + [0.0] * 5, 'not_finite'),
        ([0.0] * 5 + [math.inf], 'not_finite'),
        (np.where(np.arange(6) == 2, limits.upper_rad + 0.1, 0.0), 'limits'),
    ):
        with pytest.raises(InputError) as error:
            cell.set_joint_targets(bad)
        assert error.value.kind == kind
        np.testing.assert_array_equal(cell.joint_targets_rad, good)
    cell.step(1500)
    assert np.abs(cell.joint_positions_rad - good).max() < 0.01


def test_the_wrist_sensor_reads_the_paddle_weight_and_the_hand(cell):
    cell.step(200)
    m, d = cell.model, cell.data
    tool = m.body(robot_model.TOOL_FRAME).id
    tool_origin, rotation = cell.tool_pose()
    weight = np.array([0.0, 0.0, -world_spec.GRAVITY_M_S2 * m.body_subtreemass[tool]])
    force, torque = cell.tool_wrench()
    np.testing.assert_allclose(force, rotation.T @ weight, atol=1e-3)
    np.testing.assert_allclose(torque, rotation.T @ np.cross(d.subtree_com[tool] - tool_origin, weight), atol=1e-4)

    q_before = cell.joint_positions_rad
    cell.set_hand_wrench([10.0, 0.0, 0.0], frame='world')
    cell.step(1000)
    pushed, _ = cell.tool_wrench()
    _, rotation = cell.tool_pose()
    np.testing.assert_allclose(pushed - force, rotation.T @ [10.0, 0.0, 0.0], atol=0.1)
    assert np.abs(cell.joint_positions_rad - q_before).max() < 0.01  # the servo holds the pose

    cell.set_hand_wrench([0.0, 0.0, 10.0], [0.0, 0.0, 0.5], frame='tool0', duration_s=0.1)
    cell.step(50)
    pushed, twisted = cell.tool_wrench()
    np.testing.assert_allclose(pushed - force, [0.0, 0.0, 10.0], atol=0.1)
    assert twisted[2] == pytest.approx(0.5, abs=0.02)
    cell.step(100)  # the hand let go 0.1 s after it pushed
    released, _ = cell.tool_wrench()
    np.testing.assert_allclose(released, force, atol=0.05)


def test_the_sensor_can_also_feel_the_tools_inertia(cell):
    m = cell.model
    tool_mass_kg = m.body_subtreemass[m.body(robot_model.TOOL_FRAME).id]
    cell.step(100)
    for still_a, still_b in zip(cell.tool_wrench(), cell.tool_wrench(include_inertia=True)):
        np.testing.assert_allclose(still_a, still_b, atol=1e-6)
    cell.set_joint_targets(HOME + np.array([0.5, 0.0, 0.0, 0.0, 0.0, 0.0]))  # a brisk pan: the tool accelerates
    largest_gap_n = 0.0
    for _ in range(100):
        cell.step(1)
        environment, _ = cell.tool_wrench()
        physical, _ = cell.tool_wrench(include_inertia=True)
        largest_gap_n = max(largest_gap_n, float(np.linalg.norm(physical - environment)))
    # The difference is the tool's mass times its acceleration: clearly there, and bounded by the servo.
    assert 0.5 < largest_gap_n < tool_mass_kg * 200.0


def test_bad_hand_wrenches_are_rejected(cell):
    with pytest.raises(InputError):
        cell.set_hand_wrench([math.nan, 0.0, 0.0])
    with pytest.raises(InputError):
        cell.set_hand_wrench([1.0, 0.0, 0.0], frame='base_link')


def test_a_30_cm_drop_rebounds_like_an_ittf_ball(cell):
    cell.set_joint_targets(PARKED)
    cell.step(1500)
    cell.launch_ball([-0.5, 0.0, world_spec.TABLE_HEIGHT_M + 0.305], [0.0, 0.0, 0.0])
    heights, bounced = [], False
    for _ in range(900):
        cell.step(1)
        bounced = bounced or any(e.type == referee.BOUNCE_OWN_SIDE for e in cell.pop_events())
        if bounced:
            heights.append(cell.ball_position_m[2] - world_spec.TABLE_HEIGHT_M)
    assert 0.215 <= max(heights) <= 0.265


def test_free_flight_and_first_bounce_follow_the_world_spec_law(cell):
    launch = world_spec.incoming_ball_for_seed(3)
    expected, _, flight_s, _ = world_spec.fly_to_table(launch.position_m, launch.velocity_m_s, dt_s=cell.dt_s)
    cell.set_joint_targets(PARKED)
    cell.step(1500)
    start_s = cell.time_s
    cell.launch_ball(launch.position_m, launch.velocity_m_s)
    events = [e for e in _run_until_end(cell) if e.type == referee.BOUNCE_OWN_SIDE]
    np.testing.assert_allclose(events[0].position_m, expected, atol=1e-6)
    assert events[0].time_s - start_s == pytest.approx(flight_s, abs=1e-6)


@pytest.mark.parametrize('velocity', [(0.0, 0.0, -15.0), (-9.0, 3.0, -12.0), (-14.9, 0.0, -1.5)])
def test_nothing_tunnels_through_the_table_at_15_m_s(cell, velocity):
    cell.set_joint_targets(PARKED)
    cell.step(1500)
    height_m = world_spec.TABLE_HEIGHT_M + (0.3 if velocity[2] < -5 else 0.05)
    cell.launch_ball([-0.2, 0.0, height_m], velocity)
    lowest = math.inf
    for _ in range(60):
        cell.step(1)
        p = cell.ball_position_m
        if world_spec.on_table(p[0], p[1]):
            lowest = min(lowest, p[2])
    assert lowest >= world_spec.TABLE_CONTACT_HEIGHT_M - 1e-9
    assert cell.ball_velocity_m_s[2] > 0.0


@pytest.mark.parametrize('offset_m', [0.0, 0.0037, 0.0081])
def test_nothing_tunnels_through_the_net_at_15_m_s(cell, offset_m):
    cell.launch_ball([0.6 + offset_m, 0.1, world_spec.TABLE_HEIGHT_M + 0.08], [-15.0, 0.0, 0.0])
    crossed = False
    for _ in range(100):
        cell.step(1)
        crossed = crossed or cell.ball_position_m[0] < 0.0
    events = cell.pop_events()
    assert [e.type for e in events][:2] == [referee.LAUNCHED, referee.NET]
    assert not crossed


@pytest.mark.parametrize('speed_m_s', [3.0, 8.0, 15.0])
def test_the_paddle_returns_the_ball_with_its_restitution_without_tunnelling(cell, speed_m_s):
    centre, rotation = cell.paddle_pose()
    normal = rotation[:, 2]
    cell.launch_ball(centre + 0.25 * normal, -speed_m_s * normal)
    incoming = outgoing = None
    for _ in range(int(0.4 / speed_m_s / cell.dt_s) + 20):
        before = cell.ball_velocity_m_s
        cell.step(1)
        assert (cell.ball_position_m - centre) @ normal > 0.0  # never behind the blade's face
        if any(e.type == referee.PADDLE_HIT for e in cell.pop_events()):
            incoming, outgoing = before @ normal, cell.ball_velocity_m_s @ normal
    assert incoming < 0.0 < outgoing
    # Within one step gravity (perpendicular to the normal here) and drag change little.
    assert outgoing == pytest.approx(-world_spec.PADDLE_RESTITUTION * incoming, rel=0.01)


def test_a_ball_on_the_arm_is_a_robot_contact(cell):
    forearm = cell.model.body('forearm_link').id
    # Half-way along the forearm (the URDF's forearm runs along its link's z axis to wrist_1).
    target = cell.data.xpos[forearm] + cell.data.xmat[forearm].reshape(3, 3)[:, 2] * 0.2
    start = target + np.array([0.6, 0.0, 0.0])
    cell.launch_ball(start, [-6.0, 0.0, 0.0])
    events = _run_until_end(cell, max_s=1.0)
    assert [e.type for e in events] == [referee.LAUNCHED, referee.ROBOT_CONTACT, referee.RALLY_END]
    assert events[-1].reason == 'robot_contact'
    assert cell.ball_velocity_m_s[0] > 0.0  # it bounced off


def test_pressing_the_arm_onto_the_table_is_judged_and_resisted(cell):
    cell.launch_ball([1.0, 0.0, 1.5], [0.0, 0.0, 0.0])  # a rally in play, far from the robot
    cell.set_joint_targets(HOME + np.array([0.0, 0.9, -0.6, 0.0, 0.0, 0.0]))
    events = _run_until_end(cell, max_s=2.0)
    assert [e.type for e in events][-2:] == [referee.TABLE_CONTACT_BY_ROBOT, referee.RALLY_END]
    assert events[-1].reason == 'table_contact_by_robot'
    cell.step(500)
    paddle_centre, _ = cell.paddle_pose()
    assert paddle_centre[2] > world_spec.TABLE_HEIGHT_M  # the table stopped it


def test_seed_7_against_a_motionless_arm(cell):
    launch = world_spec.incoming_ball_for_seed(7)
    start_s = cell.time_s
    cell.launch_ball(launch.position_m, launch.velocity_m_s)
    events = _run_until_end(cell, max_s=3.0)
    assert [e.type for e in events] == [referee.LAUNCHED, referee.BOUNCE_OWN_SIDE, referee.RALLY_END]
    assert not events[-1].success and events[-1].time_s - start_s < 3.0


def test_forty_incoming_balls_need_every_stroke(cell):
    """Seeds 100-139 of the default distribution, the arm parked out of the way."""
    cell.set_joint_targets(PARKED)
    cell.step(1500)
    speeds, apex_lateral_m = [], []
    for seed in range(100, 140):
        launch = world_spec.incoming_ball_for_seed(seed)
        speeds.append(float(np.linalg.norm(launch.velocity_m_s)))
        cell.launch_ball(launch.position_m, launch.velocity_m_s)
        bounces, apex = [], None
        for _ in range(2000):
            cell.step(1)
            bounces += [
                e for e in cell.pop_events() if e.type in (referee.BOUNCE_OWN_SIDE, referee.BOUNCE_OPPONENT_SIDE)
            ]
            if bounces and cell.ball_velocity_m_s[2] <= 0.0:
                apex = cell.ball_position_m
                break
        assert bounces[0].type == referee.BOUNCE_OWN_SIDE, seed
        assert world_spec.on_table(*bounces[0].position_m[:2]) and bounces[0].position_m[0] < 0.0
        apex_lateral_m.append(apex[1])
    assert min(speeds) >= 4.0 and max(speeds) <= 6.6 and max(speeds) - min(speeds) >= 2.0
    assert max(apex_lateral_m) - min(apex_lateral_m) >= 0.8


def test_reset_removes_the_ball_and_ends_its_rally(cell):
    ball = cell.launch_ball([1.0, 0.0, 1.2], [-4.0, 0.0, 0.0])
    cell.set_joint_targets(HOME + 0.2)
    cell.step(100)
    cell.reset()
    events = cell.pop_events()
    assert (events[-1].ball_id, events[-1].type, events[-1].reason) == (ball, referee.RALLY_END, 'aborted')
    assert not cell.ball_in_play and cell.ball_position_m is None
    np.testing.assert_array_equal(cell.joint_positions_rad, HOME)
    np.testing.assert_array_equal(cell.joint_velocities_rad_s, np.zeros(6))


def test_bad_launches_are_rejected(cell):
    for position, velocity in (
        ([0.0, 0.0, math.nan], [0.0, 0.0, 0.0]),
        ([0.0, 0.0, 1.0], [40.0, 0.0, 0.0]),
        ([0.0, 0.0, -0.5], [0.0, 0.0, 0.0]),
    ):
        with pytest.raises(InputError):
            cell.launch_ball(position, velocity)
    assert not cell.ball_in_play
