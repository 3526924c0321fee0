"""The world spec's incoming balls: reproducible, and they come within the paddle's reach."""

import math

import numpy as np
import pinocchio as pin
import pytest

from stylepong_description import robot_model
from stylepong_sim import world_spec


def test_a_seed_names_one_ball_and_zero_speeds_mean_the_default_range():
    a = world_spec.incoming_ball_for_seed(11)
    b = world_spec.incoming_ball_for_seed(11, (0.0, 0.0))
    np.testing.assert_array_equal(a.position_m, b.position_m)
    np.testing.assert_array_equal(a.velocity_m_s, b.velocity_m_s)
    assert not np.array_equal(a.velocity_m_s, world_spec.incoming_ball_for_seed(12).velocity_m_s)
    low = world_spec.incoming_ball_for_seed(11, world_spec.SPEED_RANGES_M_S['low'])
    assert 4.0 <= np.linalg.norm(low.velocity_m_s) <= 4.8


def _first_reachable_point(launch: world_spec.BallLaunch) -> np.ndarray:
    """Where the rebound first enters the region the distribution promises (same law as rebound_reaches)."""
    contact_p, contact_v, _, _ = world_spec.fly_to_table(launch.position_m, launch.velocity_m_s)
    v = world_spec.contact_response(
        contact_v, np.array([0.0, 0.0, 1.0]), world_spec.TABLE_RESTITUTION, world_spec.TABLE_TANGENTIAL_FACTOR
    )
    p = contact_p.copy()
    d = world_spec.INCOMING
    for _ in range(1000):
        v = v + (np.array([0.0, 0.0, -world_spec.GRAVITY_M_S2]) + world_spec.drag_acceleration(v)) * 0.002
        p = p + v * 0.002
        if p[2] >= d.min_hit_height_m and np.linalg.norm(p - d.reach_centre_m) <= d.reach_radius_m:
            return p
    raise AssertionError('the rebound never enters the reachable region')


def _paddle_centre_ik(target_world: np.ndarray) -> float:
    """Position-only damped least squares from home; returns the remaining distance (m)."""
    model = robot_model.pinocchio_model()
    data = model.createData()
    frame = model.getFrameId(robot_model.PADDLE_CENTRE_FRAME)
    base = pin.SE3(
        pin.utils.rpyToMatrix(0.0, 0.0, world_spec.ROBOT_BASE_YAW_RAD), np.array(world_spec.ROBOT_BASE_POSITION_M)
    )
    target = base.actInv(target_world)
    limits = robot_model.joint_limits()
    q = np.array(world_spec.HOME_JOINT_POSITIONS_RAD)
    for _ in range(300):
        pin.framesForwardKinematics(model, data, q)
        error = target - data.oMf[frame].translation
        if np.linalg.norm(error) < 1e-4:
            break
        jacobian = pin.computeFrameJacobian(model, data, q, frame, pin.LOCAL_WORLD_ALIGNED)[:3]
        step = jacobian.T @ np.linalg.solve(jacobian @ jacobian.T + 1e-4 * np.eye(3), error)
        q = np.clip(q + step, limits.lower_rad, limits.upper_rad)
    pin.framesForwardKinematics(model, data, q)
    return float(np.linalg.norm(target - data.oMf[frame].translation))


@pytest.mark.parametrize('seed', [100, 105, 112, 118, 126, 131, 137])
def test_every_incoming_ball_passes_where_the_paddle_centre_can_be(seed):
    launch = world_spec.incoming_ball_for_seed(seed)
    assert _paddle_centre_ik(_first_reachable_point(launch)) < 0.005


def test_the_reach_region_is_inside_the_arms_reach():
    """Its farthest point from the reach centre, in the worst direction, is still reachable."""
    d = world_spec.INCOMING
    for azimuth in np.radians([-60.0, -30.0, 0.0, 30.0, 60.0]):
        direction = np.array([math.cos(azimuth), math.sin(azimuth), 0.25])
        point = np.array(d.reach_centre_m) + d.reach_radius_m * direction / np.linalg.norm(direction)
        assert _paddle_centre_ik(point) < 0.005, np.degrees(azimuth)
