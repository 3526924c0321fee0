"""The actuator models (ur_servoj.py): the ideal reference is world_spec's, servoj samples at its rate, lags a
ramp by about half a tick + look-ahead + 1/gain, keeps to 180 deg/s, and both cells take either."""

import math

import numpy as np
import pytest

from stylepong_sim import world_spec
from stylepong_sim.cells import ur_servoj
from stylepong_sim.cells.cell import Cell

DT = world_spec.PHYSICS_DT_S
HOME = np.array(world_spec.HOME_JOINT_POSITIONS_RAD)


def _ramp_lag_s(settings: ur_servoj.ServojSettings, speed_rad_s: float = 1.0, duration_s: float = 0.9) -> float:
    """Feed a ramp command at the policy's 60 Hz and return by how long the setpoint trails the ramp, on
    average over its last 0.4 s (past the start-up transient)."""
    servo = ur_servoj.ServojReference(HOME, settings)
    lags = []
    for k in range(1, round(duration_s / DT) + 1):
        t = k * DT
        command_t = math.floor(t * world_spec.POLICY_RATE_HZ) / world_spec.POLICY_RATE_HZ  # the player's held commands
        servo.command(HOME + speed_rad_s * command_t)
        q_ref, _ = servo.step(t, DT)
        if t > duration_s - 0.4:
            lags.append(t - (q_ref[0] - HOME[0]) / speed_rad_s)
    return float(np.mean(lags))


def test_settings_are_checked():
    with pytest.raises(ValueError, match='lookahead_s'):
        ur_servoj.ServojSettings(lookahead_s=0.01)
    with pytest.raises(ValueError, match='gain'):
        ur_servoj.ServojSettings(gain=50.0)
    with pytest.raises(ValueError, match='servo_rate_hz'):
        ur_servoj.ServojSettings(servo_rate_hz=0.0)
    with pytest.raises(ValueError, match='actuator'):
        ur_servoj.make_reference('perfect', HOME, np.full(6, 3.0))


def test_ideal_reference_is_the_rate_limited_servo_reference():
    v_max = np.array([3.15, 3.15, 3.15, 3.2, 3.2, 3.2])
    ideal = ur_servoj.IdealReference(HOME, v_max)
    ideal.command(HOME + 0.01)
    q_ref, v_ref = ideal.step(DT, DT)
    assert q_ref == pytest.approx(HOME + v_max * DT)
    assert v_ref == pytest.approx(v_max)
    for k in range(2, 6):  # arrives in the fourth step, at rest in the fifth
        q_ref, v_ref = ideal.step(k * DT, DT)
    assert q_ref == pytest.approx(HOME + 0.01) and v_ref == pytest.approx(np.zeros(6))


def test_servoj_reads_commands_only_at_its_ticks():
    servo = ur_servoj.ServojReference(HOME, ur_servoj.ServojSettings(servo_rate_hz=125.0))
    servo.step(DT, DT)  # tick at 0 passed; the next is at 8 ms
    servo.command(HOME + 0.5)
    for k in range(2, 8):
        q_ref, _ = servo.step(k * DT, DT)
    assert q_ref == pytest.approx(HOME)  # not seen before the 8 ms tick
    q_ref, _ = servo.step(8 * DT, DT)
    assert (q_ref > HOME).all()


def test_servoj_ramp_lag_is_half_a_tick_plus_lookahead_plus_inverse_gain():
    for rate_hz, lookahead_s, gain in ((125.0, 0.03, 2000.0), (500.0, 0.03, 2000.0), (125.0, 0.1, 300.0)):
        lag = _ramp_lag_s(ur_servoj.ServojSettings(rate_hz, lookahead_s, gain))
        # the 60 Hz command trails the ramp by half a policy period itself
        expected = 0.5 / world_spec.POLICY_RATE_HZ + 0.5 / rate_hz + lookahead_s + 1.0 / gain
        assert lag == pytest.approx(expected, abs=0.002), (rate_hz, lookahead_s, gain)


def test_servoj_keeps_to_the_ur_joint_speed_limit():
    servo = ur_servoj.ServojReference(HOME, ur_servoj.ServojSettings(servo_rate_hz=500.0))
    servo.command(HOME + 2.0)
    speeds = [np.abs(servo.step(k * DT, DT)[1]).max() for k in range(1, 400)]
    assert max(speeds) == pytest.approx(ur_servoj.UR_JOINT_SPEED_LIMIT_RAD_S)


@pytest.mark.parametrize('actuator', ur_servoj.ACTUATORS)
def test_the_mujoco_cell_follows_a_step_with_either_actuator(actuator):
    cell = Cell(actuator=actuator)
    target = HOME + np.array([0.2, -0.1, 0.1, 0.1, -0.1, 0.2])
    cell.set_joint_targets(target)
    cell.step_for(0.6)
    assert cell.joint_positions_rad == pytest.approx(target, abs=0.01)
    cell.reset()
    assert cell.joint_positions_rad == pytest.approx(HOME)
    with pytest.raises(ValueError, match='actuator'):
        Cell(actuator='servo')
