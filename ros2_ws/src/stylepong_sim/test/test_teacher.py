"""The virtual teacher's strokes and hand (its drag of the FDCC arm: stylepong_fdcc/test/test_teacher_drags_fdcc.py)."""

import numpy as np
import pinocchio as pin
import pytest

from stylepong_description import robot_model
from stylepong_sim import world_spec
from stylepong_sim.teaching.teacher import (
    STROKES,
    SWINGS,
    CellKinematics,
    StrokePath,
    TeacherConfig,
    VirtualTeacher,
    hand_wrench,
)

HOME = np.array(world_spec.HOME_JOINT_POSITIONS_RAD)
KIN = CellKinematics()
HOME_CENTRE = KIN.pose(HOME, KIN.frame_id(robot_model.PADDLE_CENTRE_FRAME)).translation


def sampled(path: StrokePath, dt_s: float = 0.002):
    times = np.arange(0.0, path.duration_s + 1e-9, dt_s)
    points = [path.at(t) for t in times]
    return times, np.array([p.position_m for p in points]), np.array([p.velocity_m_s for p in points])


@pytest.mark.parametrize('swing', SWINGS)
def test_the_nominal_stroke_is_at_its_top_speed_at_the_hit(swing):
    # Every take, the nominal one among them, is slow, starts and ends at rest at home and passes its hit
    # (test_teacher_variation); the nominal stroke is held closer: its top speed at the hit, its velocities
    # within 2 mm/s of the positions' derivative (3 for every take).
    path = StrokePath(swing, TeacherConfig(), HOME_CENTRE)
    times, positions, velocities = sampled(path)
    assert 1.5 <= TeacherConfig().stroke_s <= 3.0 and path.duration_s <= 3.5
    speeds = np.linalg.norm(velocities, axis=1)
    assert np.linalg.norm(path.at(path.hit_time_s()).velocity_m_s) > 0.85 * speeds.max()
    assert abs(times[np.argmax(speeds)] - path.hit_time_s()) < 0.2
    np.testing.assert_allclose(np.gradient(positions, times, axis=0)[1:-1], velocities[1:-1], atol=2e-3)


@pytest.mark.parametrize('swing', SWINGS)
def test_a_stroke_swings_back_then_forwards_through_a_hit_in_front_of_the_robot_and_clear_of_the_table(swing):
    path = StrokePath(swing, TeacherConfig(), HOME_CENTRE)
    _, positions, _ = sampled(path)
    assert path.back[0] < HOME_CENTRE[0] < path.hit[0] < path.follow[0]
    assert path.hit[0] > world_spec.ROBOT_BASE_POSITION_M[0] + 0.2
    assert path.follow[2] > path.hit[2] > path.back[2]
    # Over the table the blade stays above its surface by more than its radius.
    over_table = positions[:, 0] > -world_spec.HALF_LENGTH_M - robot_model.PADDLE.blade_radius_m
    assert np.all(positions[over_table, 2] > world_spec.TABLE_HEIGHT_M + robot_model.PADDLE.blade_radius_m)


def test_the_three_directions_are_distinct():
    hits = {s: StrokePath(s, TeacherConfig(), HOME_CENTRE).hit for s in SWINGS}
    sweeps = {
        s: StrokePath(s, TeacherConfig(), HOME_CENTRE).follow - StrokePath(s, TeacherConfig(), HOME_CENTRE).back
        for s in SWINGS
    }
    assert hits['leftward'][1] > hits['forward'][1] + 0.15  # world +y is the robot's left
    assert hits['rightward'][1] < hits['forward'][1] - 0.15
    assert sweeps['leftward'][1] > 0.2 and sweeps['rightward'][1] < -0.2 and abs(sweeps['forward'][1]) < 0.1
    assert STROKES['leftward'].hit_yaw_rad > 0 > STROKES['rightward'].hit_yaw_rad


def test_unknown_swing_and_too_slow_a_stroke_are_refused():
    with pytest.raises(ValueError, match='swing'):
        StrokePath('backhand', TeacherConfig(), HOME_CENTRE)
    with pytest.raises(ValueError, match='1.5-6 s'):
        VirtualTeacher('forward', TeacherConfig(forward_swing_s=5.5))
    with pytest.raises(ValueError, match='1.5-6 s'):
        VirtualTeacher('forward', TeacherConfig(backswing_s=0.4, forward_swing_s=1.0))


def test_the_hand_pulls_towards_the_via_point_and_never_pushes_harder_than_its_limit():
    config = TeacherConfig()
    rotation = np.eye(3)
    small = hand_wrench(config, np.zeros(3), rotation, np.zeros(6), np.array([0.01, 0, 0]), rotation, np.zeros(6))
    np.testing.assert_allclose(small, [config.hand_stiffness_n_per_m * 0.01, 0, 0, 0, 0, 0])
    far = hand_wrench(
        config, np.zeros(3), rotation, np.zeros(6), np.array([0, 5.0, 0]), pin.utils.rpyToMatrix(0, 0, 2.0), np.zeros(6)
    )
    assert np.linalg.norm(far[:3]) == pytest.approx(config.max_force_n)
    assert np.linalg.norm(far[3:]) == pytest.approx(config.max_torque_nm)
    assert far[1] > 0 and far[5] > 0


def test_the_hand_waits_for_an_arm_that_does_not_follow():
    config = TeacherConfig()
    teacher = VirtualTeacher('forward', config)
    t = 0.0
    while teacher.phase != 'ready':  # the arm at home is at the ready pose already
        teacher.update(t, HOME, np.zeros(6))
        t += 0.002
        assert t < 5.0
    teacher.begin_stroke(t)
    forces = []
    for _ in range(5000):  # 10 s with the arm stuck at home
        forces.append(np.linalg.norm(teacher.update(t, HOME, np.zeros(6))[:3]))
        t += 0.002
    assert teacher.phase == 'stroke'  # the stroke did not run on without the arm
    # The clock stops with the paddle centre lag_stop_m behind; the gripped point is further from its target
    # by the chord the opened blade turns it through about the centre.
    lever_m = float(np.linalg.norm(teacher.centre_to_grip.translation))
    chord_m = 2.0 * lever_m * np.sin(0.5 * config.blade_pitch_rad)
    assert max(forces) < config.hand_stiffness_n_per_m * (config.lag_stop_m + chord_m) + 5.0
    assert teacher.via_point(t).velocity_m_s @ teacher.via_point(t).velocity_m_s < 1e-6  # the via-point waits


def test_an_opened_blade_faces_up_from_the_back_swing_on_and_is_upright_at_the_ready_pose():
    opened = VirtualTeacher('forward', TeacherConfig(blade_pitch_rad=0.6))
    path = opened.path
    hit = path.at(path.hit_time_s())
    assert VirtualTeacher('forward').path.at(path.hit_time_s()).pitch_rad == 0.6  # the default: the shipped clips'
    upright = VirtualTeacher('forward', TeacherConfig(blade_pitch_rad=0.0)).path
    assert upright.at(upright.hit_time_s()).pitch_rad == 0.0
    assert path.at(0.0).pitch_rad == 0.0 and hit.pitch_rad == 0.6 and path.at(path.duration_s).pitch_rad == 0.6
    normal = hit.rotation(opened.home_rotation)[:, 2]  # the blade's face, +x at home
    assert normal[2] == pytest.approx(np.sin(0.6), abs=0.01) and normal[0] == pytest.approx(np.cos(0.6), abs=0.01)
    # Opening during the back-swing: the angular velocity is the rotation's rate of change.
    t, dt = TeacherConfig().lead_in_s + 0.5 * path.backswing_s, 1e-6
    before, after = path.at(t), path.at(t + dt)
    assert 0.0 < before.pitch_rad < 0.6
    turned = pin.log3(after.rotation(opened.home_rotation) @ before.rotation(opened.home_rotation).T) / dt
    np.testing.assert_allclose(turned, before.angular_velocity_rad_s(), atol=1e-4)
    with pytest.raises(ValueError, match='blade_pitch_rad'):
        TeacherConfig(blade_pitch_rad=1.2).validate()
