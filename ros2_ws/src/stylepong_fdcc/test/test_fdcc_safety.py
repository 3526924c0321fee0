"""The safety layer: wrench rejection and conditioning, tool gravity, joint limits, watchdog, enable."""

import math

import numpy as np
import pinocchio as pin
import pytest

from stylepong_description import robot_model
from stylepong_fdcc.drag_teach_controller import DragTeachController
from stylepong_fdcc.fdcc_config import FdccConfig
from stylepong_fdcc.fdcc_solver import FdccSolver
from stylepong_fdcc.joint_limits import command_limits, limit_motion
from stylepong_fdcc.wrench_conditioning import (
    WrenchConditioner,
    deadband_and_clamp,
    gravity_wrench_on_tool,
    tool_load_from_model,
    wrench_fault,
)
from stylepong_sim.world_spec import HOME_JOINT_POSITIONS_RAD

HOME = np.array(HOME_JOINT_POSITIONS_RAD)
MODEL = robot_model.pinocchio_model()
DATA = MODEL.createData()
GRAVITY = np.array(MODEL.gravity.linear)


def tool_rotation(q):
    pin.framesForwardKinematics(MODEL, DATA, q)
    return DATA.oMf[MODEL.getFrameId(robot_model.TOOL_FRAME)].rotation.copy()


def weight_reading(q, extra_force_base=np.zeros(3)):
    """What an ideal sensor in tool0 reads: the paddle's weight (plus a hand force at tool0)."""
    rotation = tool_rotation(q)
    load = tool_load_from_model(MODEL)
    reading = gravity_wrench_on_tool(load, rotation, GRAVITY)
    reading[:3] += rotation.T @ extra_force_base
    return reading


# --- rejection ---
@pytest.mark.parametrize(
    'wrench',
    [
        [math.nan, 0, 0, 0, 0, 0],
        [0, 0, 0, math.inf, 0, 0],
        [0, -math.inf, 0, 0, 0, 0],
        [1e6, 0, 0, 0, 0, 0],
        [0, 0, -1e6, 0, 0, 0],
        [0, 0, 0, 0, 0, 1e6],
    ],
)
def test_non_finite_and_implausible_wrenches_are_rejected(wrench):
    assert wrench_fault(np.array(wrench, dtype=float), 500.0, 50.0) is not None


def test_a_normal_wrench_is_accepted():
    assert wrench_fault(np.array([10.0, -5.0, 3.0, 0.5, 0.1, 0.0]), 500.0, 50.0) is None


# --- conditioning ---
def test_tool_load_is_the_paddle_of_the_robot_model():
    load = tool_load_from_model(MODEL)
    assert load.mass_kg == pytest.approx(robot_model.PADDLE.mass_kg)
    # The centre of mass lies on the handle axis (tool0 z), between the flange and the blade centre.
    assert abs(load.com_m[0]) < 1e-12 and abs(load.com_m[1]) < 1e-12
    assert 0.0 < load.com_m[2] < robot_model.PADDLE.centre_offset_m


@pytest.mark.parametrize('q', [HOME, HOME + np.array([0.3, 0.2, -0.4, 0.8, 0.5, 1.0]), np.zeros(6)])
def test_gravity_compensation_removes_the_paddle_weight_at_any_orientation(q):
    config = FdccConfig(force_deadband_n=0.0, torque_deadband_nm=0.0)
    conditioner = WrenchConditioner(config, tool_load_from_model(MODEL), GRAVITY)
    hand = np.array([3.0, -2.0, 1.0])
    for k in range(200):
        conditioner.add_sample(weight_reading(q, hand), tool_rotation(q), k * 0.002)
    out = conditioner.output()
    np.testing.assert_allclose(out[:3], hand, atol=1e-9)
    np.testing.assert_allclose(out[3:], 0.0, atol=1e-9)


def test_without_compensation_the_weight_would_push_the_arm():
    config = FdccConfig(gravity_compensation=False, force_deadband_n=0.0)
    conditioner = WrenchConditioner(config, tool_load_from_model(MODEL), GRAVITY)
    for k in range(200):
        conditioner.add_sample(weight_reading(HOME), tool_rotation(HOME), k * 0.002)
    assert conditioner.output()[2] == pytest.approx(-robot_model.PADDLE.mass_kg * 9.81, rel=1e-3)


def test_tare_removes_a_sensor_bias():
    config = FdccConfig(force_deadband_n=0.0, torque_deadband_nm=0.0)
    conditioner = WrenchConditioner(config, tool_load_from_model(MODEL), GRAVITY)
    bias = np.array([2.0, -1.5, 4.0, 0.2, -0.1, 0.05])
    t = 0.0
    for _ in range(150):
        conditioner.add_sample(weight_reading(HOME) + bias, tool_rotation(HOME), t)
        t += 0.002
    assert conditioner.can_tare(t)
    np.testing.assert_allclose(conditioner.tare(), bias, atol=1e-9)
    for _ in range(10):
        conditioner.add_sample(weight_reading(HOME) + bias, tool_rotation(HOME), t)
        t += 0.002
    np.testing.assert_allclose(conditioner.output(), 0.0, atol=1e-9)


def test_deadband_shrinks_continuously_and_the_clamp_keeps_direction():
    np.testing.assert_array_equal(deadband_and_clamp(np.array([0.6, 0.0, 0.8]), 1.0, 40.0), 0.0)
    np.testing.assert_allclose(deadband_and_clamp(np.array([3.0, 4.0, 0.0]), 1.0, 40.0), [2.4, 3.2, 0.0])
    clamped = deadband_and_clamp(np.array([300.0, 400.0, 0.0]), 1.0, 40.0)
    np.testing.assert_allclose(clamped, [24.0, 32.0, 0.0])


@pytest.mark.parametrize('sample_rate_hz', [250.0, 1000.0])
def test_low_pass_time_constant_does_not_depend_on_the_sample_rate(sample_rate_hz):
    config = FdccConfig(lowpass_cutoff_hz=10.0, force_deadband_n=0.0)
    conditioner = WrenchConditioner(config, tool_load_from_model(MODEL), GRAVITY)
    step = weight_reading(HOME, np.array([10.0, 0.0, 0.0]))
    conditioner.add_sample(weight_reading(HOME), tool_rotation(HOME), 0.0)
    tau_s = 1.0 / (2 * math.pi * 10.0)
    n = int(round(tau_s * sample_rate_hz))
    for k in range(1, n + 1):
        conditioner.add_sample(step, tool_rotation(HOME), k / sample_rate_hz)
    assert conditioner.output()[0] == pytest.approx(10.0 * (1 - math.exp(-n / sample_rate_hz / tau_s)), rel=1e-6)
    assert conditioner.output()[0] == pytest.approx(10.0 * (1 - math.exp(-1)), rel=0.05)


# --- joint limits ---
def test_motion_limits_hold_whatever_velocity_is_wanted():
    limits = command_limits(FdccConfig())
    rng = np.random.default_rng(0)
    q, qdot, dt = HOME.copy(), np.zeros(6), 0.002
    for _ in range(3000):
        wanted = rng.normal(0.0, 50.0, 6)
        new_q, new_qdot = limit_motion(q, qdot, wanted, dt, limits)
        assert np.all(new_q >= limits.lower_rad) and np.all(new_q <= limits.upper_rad)
        assert np.all(np.abs(new_qdot) <= limits.velocity_rad_s + 1e-12)
        assert np.all(np.abs(new_q - q) <= limits.velocity_rad_s * dt + 1e-12)
        assert np.all(np.abs(new_qdot - qdot) <= limits.acceleration_rad_s2 * dt + 1e-9)
        q, qdot = new_q, new_qdot


def test_commands_step_no_further_than_the_velocity_limit_per_nominal_period_and_catch_up():
    config = FdccConfig(acceleration_limit_rad_s2=(1e3,) * 6)
    solver = FdccSolver(config)
    solver.reset(HOME)
    step_limit = solver.limits.velocity_rad_s * config.nominal_period_s
    wrench = np.array([40.0, 0, 0, 0, 0, 0])
    commands = [solver.step(wrench, 0.002) for _ in range(50)]
    commands += [solver.step(wrench, 0.004) for _ in range(20)]  # every other tick skipped: still integrated
    commands += [solver.step(np.zeros(6), 0.002) for _ in range(500)]
    steps = np.abs(np.diff(np.array(commands), axis=0))
    assert np.all(steps <= step_limit + 1e-12)
    np.testing.assert_allclose(commands[-1], solver.q)  # caught up once at rest
    # and skipped ticks cost no displacement: the same push at a steady rate ends at the same place
    steady = FdccSolver(config)
    steady.reset(HOME)
    for _ in range(50 + 40):
        steady.step(wrench, 0.002)
    for _ in range(500):
        steady.step(np.zeros(6), 0.002)
    assert np.linalg.norm(steady.pose().translation - solver.pose(commands[-1]).translation) < 0.005


def test_after_a_stall_the_arm_carries_on_instead_of_jumping():
    config = FdccConfig()
    solver = FdccSolver(config)
    solver.reset(HOME)
    wrench = np.array([20.0, 0, 0, 0, 0, 0])
    for _ in range(200):
        solver.step(wrench, 0.002)
    before = solver.pose().translation.copy()
    speed = np.linalg.norm(solver.twist()[:3])
    solver.step(wrench, 0.05)  # 50 ms without a cycle
    jump = np.linalg.norm(solver.pose().translation - before)
    assert jump <= speed * config.max_late_periods * config.nominal_period_s * 1.05


def test_velocity_and_acceleration_limits_keep_the_direction_of_motion():
    limits = command_limits(FdccConfig())
    wanted = np.array([10.0, -5.0, 2.0, 1.0, 0.0, 0.5])
    _, qdot = limit_motion(HOME, np.zeros(6), wanted, 0.002, limits)
    assert np.dot(qdot, wanted) / (np.linalg.norm(qdot) * np.linalg.norm(wanted)) == pytest.approx(1.0)


def test_a_strong_push_stops_the_elbow_inside_its_limit_with_margin():
    config = FdccConfig()
    solver = FdccSolver(config)
    q0 = HOME.copy()
    q0[2] = math.pi - 0.3  # elbow close to its +pi limit
    solver.reset(q0)
    upper = robot_model.joint_limits().upper_rad - config.position_margin_rad
    for _ in range(1000):
        pin.computeJointJacobians(solver.model, solver.data, solver.q)
        jacobian = pin.getFrameJacobian(solver.model, solver.data, solver.frame_id, pin.LOCAL_WORLD_ALIGNED)
        # The tool wrench whose joint torque is a pure torque on the elbow, towards +pi.
        wrench = np.linalg.solve(jacobian.T, 5.0 * np.eye(6)[2])
        q = solver.step(wrench, 0.002)
        assert np.all(q <= upper + 1e-12)
    assert q[2] > upper[2] - 0.05  # it did go there


# --- controller: waiting, watchdog, enable ---
def feed(controller, t, q=HOME, hand=np.zeros(3), wrench=None):
    controller.on_joint_positions(q, t)
    controller.on_wrench(weight_reading(q, hand) if wrench is None else wrench, t)


def tared_controller() -> tuple[DragTeachController, float]:
    """A controller after 0.4 s of fresh inputs at home (tared, running), and the time reached."""
    controller = DragTeachController(FdccConfig())
    t = 0.0
    for _ in range(200):
        feed(controller, t)
        controller.tick(t)
        t += 0.002
    return controller, t


def test_no_command_before_joint_states_wrenches_and_a_tare():
    controller = DragTeachController(FdccConfig())
    assert controller.tick(0.0).command is None
    t = 0.0
    while t < 0.05:
        feed(controller, t)
        assert controller.tick(t).command is None  # the tare window is not full yet
        t += 0.002
    while controller.tick(t).command is None:
        feed(controller, t)
        t += 0.002
        assert t < 0.3
    np.testing.assert_allclose(controller.tick(t).command, HOME)


def test_stale_wrench_decelerates_and_holds_then_resumes():
    config = FdccConfig()
    controller = DragTeachController(config)
    t = 0.0
    for _ in range(150):  # at rest: tare
        feed(controller, t)
        controller.tick(t)
        t += 0.002
    for _ in range(400):  # 0.8 s pushing: moving
        feed(controller, t, hand=np.array([6.0, 0.0, 0.0]))
        result = controller.tick(t)
        t += 0.002
    assert result.state == 'running' and np.max(np.abs(controller.solver.qdot)) > 0.05
    previous = result.command
    states, steps = [], []
    for _ in range(500):  # only joint states: the wrench goes stale
        controller.on_joint_positions(HOME, t)
        result = controller.tick(t)
        states.append(result.state)
        steps.append(np.max(np.abs(result.command - previous)))
        previous = result.command
        t += 0.002
    assert states[10] == 'running' and states[-1] == 'holding'
    assert 'holding' in states[: int(0.06 / 0.002)]
    assert steps[-1] == 0.0  # at rest, holding
    assert np.all(np.abs(controller.solver.qdot) == 0.0)
    speeds = []
    for _ in range(300):
        feed(controller, t, hand=np.array([6.0, 0.0, 0.0]))
        result = controller.tick(t)
        speeds.append(np.linalg.norm(controller.solver.twist()[:3]))
        t += 0.002
    assert result.state == 'running' and np.max(np.abs(controller.solver.qdot)) > 0.05
    # The push fades back in over resume_ramp_s: no lurch when the inputs come back.
    steady_m_s = (6.0 - config.force_deadband_n) / config.damping[0]
    assert speeds[5] < 0.2 * steady_m_s and speeds[-1] > 0.9 * steady_m_s


def test_garbage_wrenches_are_counted_and_do_not_count_as_fresh():
    controller, t = tared_controller()
    for k in range(100):
        controller.on_joint_positions(HOME, t)
        controller.on_wrench(np.array([math.nan, 1e6, -1e6, math.inf, 0, 0])[np.roll(np.arange(6), k)], t)
        result = controller.tick(t)
        assert result.command is not None and np.all(np.isfinite(result.command))
        t += 0.002
    assert result.state == 'holding'
    assert controller.rejected_wrenches == 100


def test_disabled_publishes_nothing_and_enabling_resyncs_to_the_measured_arm():
    controller, t = tared_controller()
    controller.set_enabled(False)
    feed(controller, t)
    assert controller.tick(t).command is None
    moved = HOME + 0.1
    for _ in range(200):
        feed(controller, t, q=moved)
        t += 0.002
    controller.set_enabled(True)
    result = controller.tick(t)
    np.testing.assert_allclose(result.command, moved)
