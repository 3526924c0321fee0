"""The FDCC solver alone: admittance, rate independence, stiffness, the two dynamics models."""

import numpy as np
import pinocchio as pin
import pytest

from stylepong_fdcc.compare_dynamics_models import simulate_push
from stylepong_fdcc.fdcc_config import FdccConfig
from stylepong_fdcc.fdcc_solver import FdccSolver, dynamics_model
from stylepong_sim.world_spec import HOME_JOINT_POSITIONS_RAD

HOME = np.array(HOME_JOINT_POSITIONS_RAD)


def push(config: FdccConfig, force, rate_hz: float, push_s: float = 1.0, total_s: float = 3.0):
    """Final tool displacement (m) after a constant force at tool0 for push_s, then none."""
    solver = FdccSolver(config)
    solver.reset(HOME)
    start = solver.pose().translation.copy()
    wrench = np.concatenate([force, np.zeros(3)]).astype(float)
    dt = 1.0 / rate_hz
    for k in range(int(round(total_s * rate_hz))):
        solver.step(wrench if k < round(push_s * rate_hz) else np.zeros(6), dt)
    return solver.pose().translation - start, solver


@pytest.mark.parametrize('model', ['virtual', 'urdf'])
def test_same_push_moves_the_tool_the_same_at_250_and_1000_hz(model):
    slow, _ = push(FdccConfig(dynamics_model=model, nominal_period_s=1 / 250), [10.0, 0, 0], 250.0)
    fast, _ = push(FdccConfig(dynamics_model=model, nominal_period_s=1 / 1000), [10.0, 0, 0], 1000.0)
    assert np.linalg.norm(fast) > 0.05
    assert np.linalg.norm(slow - fast) / np.linalg.norm(fast) < 0.05


@pytest.mark.parametrize('force', [[10.0, 0, 0], [0, -10.0, 0], [0, 0, 10.0], [6.0, 6.0, -3.0]])
def test_a_push_moves_the_tool_along_it_by_impulse_over_damping(force):
    config = FdccConfig()
    displacement, solver = push(config, np.array(force), 500.0)
    direction = np.array(force) / np.linalg.norm(force)
    assert displacement @ direction / np.linalg.norm(displacement) > 0.99
    # Linear damping: a 1 s push of |F| comes to rest |F| * 1 s / K_D further on.
    expected_m = np.linalg.norm(force) * 1.0 / config.damping[0]
    assert np.linalg.norm(displacement) == pytest.approx(expected_m, rel=0.1)
    assert np.max(np.abs(solver.qdot)) < 1e-3  # at rest again


def test_without_a_push_the_arm_does_not_move_at_all():
    solver = FdccSolver(FdccConfig())
    solver.reset(HOME)
    for _ in range(5000):
        q = solver.step(np.zeros(6), 0.002)
    np.testing.assert_array_equal(q, np.clip(HOME, solver.limits.lower_rad, solver.limits.upper_rad))


def test_stiffness_pulls_the_tool_to_the_target_and_a_push_deflects_it_by_force_over_stiffness():
    config = FdccConfig(stiffness=(200.0, 200.0, 200.0, 20.0, 20.0, 20.0))
    solver = FdccSolver(config)
    solver.reset(HOME)
    start = solver.pose()
    target = start.translation + np.array([0.05, -0.03, 0.02])
    rotation = pin.utils.rpyToMatrix(0.0, 0.0, 0.2) @ start.rotation
    solver.set_target(target, rotation)
    for _ in range(2500):
        solver.step(np.zeros(6), 0.002)
    pose = solver.pose()
    assert np.linalg.norm(pose.translation - target) < 1e-3
    assert np.linalg.norm(pin.log3(rotation @ pose.rotation.T)) < 1e-3
    for _ in range(2500):
        solver.step(np.array([10.0, 0, 0, 0, 0, 0]), 0.002)
    assert solver.pose().translation[0] - target[0] == pytest.approx(10.0 / 200.0, rel=0.05)


def test_the_virtual_model_follows_the_hand_better_than_the_urdf_model():
    """The figures behind the default (module docstring): faster response, less coasting."""
    virtual = simulate_push(FdccConfig(dynamics_model='virtual'), HOME, np.array([10.0, 0, 0]), 1.0, 4.0, 500.0)
    urdf = simulate_push(FdccConfig(dynamics_model='urdf'), HOME, np.array([10.0, 0, 0]), 1.0, 4.0, 500.0)
    assert virtual['rise_s'] < 0.5 * urdf['rise_s']
    assert virtual['coast_m'] < 0.5 * urdf['coast_m']
    assert virtual['rest_after_s'] < urdf['rest_after_s']
    assert FdccConfig().dynamics_model == 'virtual'


def test_the_urdf_model_has_the_robots_mass_and_no_gravity():
    urdf = dynamics_model(FdccConfig(dynamics_model='urdf'))
    virtual = dynamics_model(FdccConfig(dynamics_model='virtual'))
    assert sum(i.mass for i in urdf.inertias) > 15.0
    assert sum(i.mass for i in virtual.inertias[1:]) == pytest.approx(5 * 0.1 + 1.0)
    assert np.all(urdf.gravity.linear == 0) and np.all(virtual.gravity.linear == 0)


@pytest.mark.parametrize(
    'bad',
    [
        dict(damping=(30.0, 30.0, 30.0, 3.0, 3.0)),
        dict(damping=(0.0,) * 6),
        dict(stiffness=(-1.0,) * 6),
        dict(dynamics_model='heavy'),
        dict(velocity_limit_scale=1.5),
        dict(lowpass_cutoff_hz=float('nan')),
        dict(max_force_n=600.0),
    ],
)
def test_bad_settings_are_refused_with_the_name(bad):
    with pytest.raises(ValueError, match=next(iter(bad)).split('_')[0]):
        FdccSolver(FdccConfig(**bad))
