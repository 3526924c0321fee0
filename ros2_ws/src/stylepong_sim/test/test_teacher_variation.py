"""Seeded take-to-take variation of the virtual teacher's strokes (teacher.sample_variation).

The arm is dragged by the paddle's full pose, so the joint path a take asks for is the inverse kinematics
of its via-points, followed continuously from home the way the dragged arm moves: that is what the
joint-limit, shoulder and elbow checks below run on.
"""

import itertools

import numpy as np
import pinocchio as pin
import pytest

from stylepong_description import robot_model
from stylepong_sim import world_spec
from stylepong_sim.teaching.teacher import (
    MAX_SIDE_REACH_M,
    STROKES,
    SWINGS,
    VARIATION_RANGES,
    CellKinematics,
    StrokePath,
    SwingVariation,
    TeacherConfig,
    sample_variation,
)

HOME_Q = np.array(world_spec.HOME_JOINT_POSITIONS_RAD)
KIN = CellKinematics()
CENTRE = KIN.frame_id(robot_model.PADDLE_CENTRE_FRAME)
WRIST = KIN.frame_id('wrist_3_joint')  # where the axes of wrists 2 and 3 meet
HOME_POSE = KIN.pose(HOME_Q, CENTRE)
HOME_CENTRE = HOME_POSE.translation
SHIPPED_SEEDS = {'forward': (1, 4, 7), 'leftward': (2, 5), 'rightward': (3, 6)}  # tools/record_demos.sh

# Margins the tests hold every take to (the reasons are beside VARIATION_RANGES in teacher.py).
MIN_SHOULDER_CLEARANCE_M = 0.22  # nominal strokes: 0.23 m at the back-swing; takes only make it shallower
MIN_ELBOW_BEND_RAD = 1.0  # follow-throughs stay short of the arm's reach
MIN_REACHING_ELBOW_BEND_RAD = 0.5  # a stroke reaching out (side_reach_m) stretches the arm further, never straight
MAX_JOINT_STEP_RAD = 0.15  # per 20 ms of the path: more would be a flip of the shoulder or wrist
SIDE_HIT_MIN_Y_M = 0.09  # a leftward (rightward) hit this far to the left (right) of home, at least
FORWARD_HIT_MAX_Y_M = 0.03  # a forward hit this close to straight ahead
MIN_HIT_SPEED_FRACTION = 0.75  # of the take's top speed (0.85 for the nominal strokes)
DIFFERENT_TAKES_MIN_RMS_M = 0.004  # two seeds' paddle paths (on normalised time) differ by this much at least


def sampled(path: StrokePath, dt_s: float = 0.002):
    times = np.arange(0.0, path.duration_s + 1e-9, dt_s)
    points = [path.at(t) for t in times]
    return (
        times,
        np.array([p.position_m for p in points]),
        np.array([p.velocity_m_s for p in points]),
        np.array([p.yaw_rad for p in points]),
    )


def on_normalised_time(path: StrokePath, samples: int = 200) -> np.ndarray:
    """Paddle-centre positions at `samples` instants spread evenly over the clip, whatever its length."""
    return np.array([path.at(t).position_m for t in np.linspace(0.0, path.duration_s, samples)])


def joint_path(path: StrokePath, dt_s: float = 0.02) -> np.ndarray:
    """Joint positions that put the paddle centre on the via-points, followed from home (damped least squares)."""
    q = HOME_Q.copy()
    trajectory = []
    for t in np.arange(0.0, path.duration_s + 1e-9, dt_s):
        via = path.at(t)
        target = pin.SE3(world_spec.yaw_rotation(via.yaw_rad) @ HOME_POSE.rotation, via.position_m)
        for _ in range(30):
            current = KIN.pose(q, CENTRE)
            error = np.concatenate(
                [target.translation - current.translation, pin.log3(target.rotation @ current.rotation.T)]
            )
            if np.linalg.norm(error) < 1e-8:
                break
            pin.computeJointJacobians(KIN.model, KIN.data, q)
            jacobian = pin.getFrameJacobian(KIN.model, KIN.data, CENTRE, pin.LOCAL_WORLD_ALIGNED)
            q = q + jacobian.T @ np.linalg.solve(jacobian @ jacobian.T + 1e-8 * np.eye(6), error)
        assert np.linalg.norm(error) < 1e-6, f'no joint position reaches the via-point at {t:.2f} s'
        trajectory.append(q.copy())
    return np.array(trajectory)


def shoulder_clearance_m(q: np.ndarray) -> float:
    """Distance of the wrist from the plane of the shoulder's two axes (zero: the UR5's shoulder singularity)."""
    pin.framesForwardKinematics(KIN.model, KIN.data, q)
    shoulder = KIN.data.oMi[2]  # shoulder_lift_joint, rotating about its y axis
    lift_axis = shoulder.rotation[:, 1]
    normal = np.cross([0.0, 0.0, 1.0], lift_axis)
    normal /= np.linalg.norm(normal)
    return float(abs((KIN.data.oMf[WRIST].translation - shoulder.translation) @ normal))


def extreme_takes(swing: str) -> list[SwingVariation]:
    """The corners of the ranges that reach furthest: largest amplitude, every key-pose jitter at its ends."""
    r = VARIATION_RANGES
    takes = []
    for signs in itertools.product((-1.0, 1.0), repeat=3):
        delta = tuple(s * j for s, j in zip(signs, r.key_pose_jitter_m))
        for hit_fraction in r.hit_fraction:
            takes.append(
                SwingVariation(
                    amplitude_scale=r.amplitude_scale[1],
                    hit_delta_m=delta,
                    follow_delta_m=delta,
                    back_delta_m=(r.back_shallower_m[0],) + delta[1:],
                    hit_fraction=hit_fraction,
                    yaw_delta_rad=tuple(s * r.yaw_jitter_rad for s in signs),
                )
            )
    return takes


# --- seeds ---
@pytest.mark.parametrize('swing', SWINGS)
def test_the_same_seed_gives_the_same_take(swing):
    first, again = sample_variation(swing, 11), sample_variation(swing, 11)
    assert first == again
    np.testing.assert_array_equal(
        on_normalised_time(StrokePath(swing, TeacherConfig(), HOME_CENTRE, first)),
        on_normalised_time(StrokePath(swing, TeacherConfig(), HOME_CENTRE, again)),
    )


@pytest.mark.parametrize('swing', SWINGS)
def test_different_seeds_give_takes_that_differ_by_more_than_the_margin(swing):
    paths = [
        on_normalised_time(StrokePath(swing, TeacherConfig(), HOME_CENTRE, sample_variation(swing, seed)))
        for seed in range(20)
    ]
    for a, b in itertools.combinations(range(len(paths)), 2):
        rms_m = float(np.sqrt(np.mean(np.sum((paths[a] - paths[b]) ** 2, axis=1))))
        assert rms_m > DIFFERENT_TAKES_MIN_RMS_M, f'seeds {a} and {b}: paths {rms_m * 1000:.1f} mm apart'
    assert len({sample_variation(swing, seed).forward_swing_scale for seed in range(20)}) == 20


def test_strength_zero_is_the_nominal_stroke_and_any_strength_stays_within_the_ranges():
    assert sample_variation('forward', 5, strength=0.0) == SwingVariation()
    for swing, seed, strength in itertools.product(SWINGS, range(50), (0.3, 1.0)):
        sample_variation(swing, seed, strength).validate()  # raises outside the ranges
    with pytest.raises(ValueError, match='seed'):
        sample_variation('forward', -1)
    with pytest.raises(ValueError, match='strength'):
        sample_variation('forward', 1, strength=1.5)


@pytest.mark.parametrize(
    'bad',
    [
        dict(amplitude_scale=1.2),
        dict(backswing_scale=0.5),
        dict(hit_fraction=0.7),
        dict(back_delta_m=(-0.02, 0.0, 0.0)),
        dict(hit_delta_m=(0.0, 0.05, 0.0)),
        dict(yaw_delta_rad=(0.0, 0.2, 0.0)),
    ],
)
def test_a_take_outside_the_ranges_is_refused(bad):
    with pytest.raises(ValueError):
        StrokePath('forward', TeacherConfig(), HOME_CENTRE, SwingVariation(**bad))


# --- every take is a clean stroke of its label ---
@pytest.mark.parametrize('swing', SWINGS)
def test_every_take_is_a_slow_stroke_through_its_hit_near_top_speed(swing):
    takes = {'nominal': SwingVariation(), **{seed: sample_variation(swing, seed) for seed in range(30)}}
    for seed, variation in takes.items():
        path = StrokePath(swing, TeacherConfig(), HOME_CENTRE, variation)
        times, positions, velocities, _ = sampled(path)
        assert 1.5 <= path.stroke_s <= 3.0
        np.testing.assert_allclose(positions[0], HOME_CENTRE)
        assert np.linalg.norm(velocities[0]) == 0.0 and np.linalg.norm(velocities[-1]) == 0.0
        speeds = np.linalg.norm(velocities, axis=1)
        assert speeds.max() < 1.0
        hit = path.at(path.hit_time_s())
        np.testing.assert_allclose(hit.position_m, path.hit, atol=1e-9)
        assert np.linalg.norm(hit.velocity_m_s) >= MIN_HIT_SPEED_FRACTION * speeds.max(), f'seed {seed}'
        np.testing.assert_allclose(np.gradient(positions, times, axis=0)[1:-1], velocities[1:-1], atol=3e-3)
        np.testing.assert_allclose(path.at(path.duration_s).position_m, path.follow, atol=1e-9)


@pytest.mark.parametrize('swing', SWINGS)
def test_every_take_keeps_its_direction_and_its_order_and_clears_the_table(swing):
    takes = [sample_variation(swing, seed) for seed in range(200)] + extreme_takes(swing)
    takes += [dataclass_with(t, amplitude_scale=VARIATION_RANGES.amplitude_scale[0]) for t in extreme_takes(swing)]
    for take in takes:
        path = StrokePath(swing, TeacherConfig(), HOME_CENTRE, take)
        hit_y_m = path.hit[1] - HOME_CENTRE[1]
        sweep_y_m = path.follow[1] - path.back[1]
        _, hit_yaw_rad, _ = path.yaws[1:]
        if swing == 'leftward':  # world +y is the robot's left
            assert hit_y_m > SIDE_HIT_MIN_Y_M and sweep_y_m > 0.2 and hit_yaw_rad > 0.2, take
        elif swing == 'rightward':
            assert hit_y_m < -SIDE_HIT_MIN_Y_M and sweep_y_m < -0.2 and hit_yaw_rad < -0.2, take
        else:
            assert abs(hit_y_m) < FORWARD_HIT_MAX_Y_M and abs(sweep_y_m) < 0.1 and abs(hit_yaw_rad) < 0.1, take
        assert path.back[0] < HOME_CENTRE[0] - 0.05 and HOME_CENTRE[0] < path.hit[0] < path.follow[0], take
        assert path.back[0] >= HOME_CENTRE[0] + STROKES[swing].back_offset_m[0] - 1e-12  # never deeper
        assert path.follow[2] > path.hit[2] > path.back[2], take
        _, positions, _, _ = sampled(path, 0.01)
        over_table = positions[:, 0] > -world_spec.HALF_LENGTH_M - robot_model.PADDLE.blade_radius_m
        assert np.all(positions[over_table, 2] > world_spec.TABLE_HEIGHT_M + robot_model.PADDLE.blade_radius_m), take


def dataclass_with(take: SwingVariation, **changes) -> SwingVariation:
    return SwingVariation(**{**take.__dict__, **changes})


@pytest.mark.parametrize('swing', SWINGS)
def test_every_take_stays_within_the_joint_limits_clear_of_the_shoulder_singularity_and_short_of_full_reach(swing):
    limits = robot_model.joint_limits()
    takes = [SwingVariation()] + [sample_variation(swing, seed) for seed in (0, *SHIPPED_SEEDS[swing], 8, 9)]
    takes += extreme_takes(swing)[::3]
    for take in takes:
        q = joint_path(StrokePath(swing, TeacherConfig(), HOME_CENTRE, take))
        assert np.all(q > limits.lower_rad) and np.all(q < limits.upper_rad), take
        assert np.max(np.abs(np.diff(q, axis=0))) < MAX_JOINT_STEP_RAD, take
        clearance_m = min(shoulder_clearance_m(a) for a in q)
        assert clearance_m > MIN_SHOULDER_CLEARANCE_M, f'{take}: wrist {clearance_m:.3f} m from the shoulder plane'
        elbow_rad = float(np.min(np.abs(q[:, 2])))
        assert elbow_rad > MIN_ELBOW_BEND_RAD, f'{take}: elbow bent only {elbow_rad:.2f} rad'


@pytest.mark.parametrize('swing', SWINGS)
def test_a_turned_stroke_is_the_same_joint_path_with_the_shoulder_pan_moved_towards_its_side(swing):
    """TeacherConfig.side_turn_rad swings a sideways stroke round the shoulder pan's axis: from the end of
    the back-swing on only the pan joint differs, by the turn towards the stroke's side (the back-swing
    goes straight from home to the turned pose); forward strokes are not turned."""
    turn_rad = 0.5
    take = sample_variation(swing, 3)
    plain = StrokePath(swing, TeacherConfig(), HOME_CENTRE, take)
    turned = StrokePath(swing, TeacherConfig(side_turn_rad=turn_rad), HOME_CENTRE, take)
    q_plain, q_turned = joint_path(plain), joint_path(turned)
    side = {'forward': 0.0, 'leftward': 1.0, 'rightward': -1.0}[swing]
    assert np.allclose(q_turned[0], q_plain[0], atol=1e-9)
    swing_start = int(np.ceil((plain.config.lead_in_s + plain.backswing_s) / 0.02))
    np.testing.assert_allclose(q_turned[swing_start:, 0] - q_plain[swing_start:, 0], side * turn_rad, atol=1e-6)
    np.testing.assert_allclose(q_turned[swing_start:, 1:], q_plain[swing_start:, 1:], atol=1e-6)
    limits = robot_model.joint_limits()
    assert np.all(q_turned > limits.lower_rad) and np.all(q_turned < limits.upper_rad)
    assert np.max(np.abs(np.diff(q_turned, axis=0))) < MAX_JOINT_STEP_RAD
    assert min(shoulder_clearance_m(a) for a in q_turned) > MIN_SHOULDER_CLEARANCE_M
    assert side * (turned.hit[1] - plain.hit[1]) >= (0.1 if side else 0.0)
    with pytest.raises(ValueError, match='side_turn_rad'):
        TeacherConfig(side_turn_rad=1.5).validate()


@pytest.mark.parametrize('swing', ['leftward', 'rightward'])
def test_a_reaching_stroke_is_carried_to_its_side_within_the_arms_reach(swing):
    """TeacherConfig.side_reach_m carries a sideways stroke's key poses further to its side, as far as
    MAX_SIDE_REACH_M allows: the arm stays inside its joint limits, clear of the shoulder singularity and
    short of a straight elbow, and moves smoothly. Further than the limit, or for a forward stroke, the
    config is refused or ignored."""
    reach_m = MAX_SIDE_REACH_M[swing]
    take = sample_variation(swing, 3)
    plain = StrokePath(swing, TeacherConfig(), HOME_CENTRE, take)
    reached = StrokePath(swing, TeacherConfig(side_reach_m=reach_m), HOME_CENTRE, take)
    side = {'leftward': 1.0, 'rightward': -1.0}[swing]
    for key in ('back', 'hit', 'follow'):
        np.testing.assert_allclose(getattr(reached, key) - getattr(plain, key), [0.0, side * reach_m, 0.0], atol=1e-12)
    q = joint_path(reached)
    limits = robot_model.joint_limits()
    assert np.all(q > limits.lower_rad) and np.all(q < limits.upper_rad)
    assert np.max(np.abs(np.diff(q, axis=0))) < MAX_JOINT_STEP_RAD
    assert min(shoulder_clearance_m(a) for a in q) > MIN_SHOULDER_CLEARANCE_M
    assert float(np.min(np.abs(q[:, 2]))) > MIN_REACHING_ELBOW_BEND_RAD
    with pytest.raises(ValueError, match='side_reach_m'):
        StrokePath(swing, TeacherConfig(side_reach_m=reach_m + 0.05), HOME_CENTRE, take)
    forward = StrokePath('forward', TeacherConfig(side_reach_m=0.1), HOME_CENTRE, sample_variation('forward', 3))
    np.testing.assert_array_equal(
        forward.hit, StrokePath('forward', TeacherConfig(), HOME_CENTRE, sample_variation('forward', 3)).hit
    )
