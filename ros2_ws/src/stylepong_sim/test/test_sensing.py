"""Sensor models and sample clocks of the cell."""

import numpy as np
import pytest

from stylepong_sim.cells.sensing import BallCamera, ForceTorqueSensor, SampleClock, SensingConfig

DT_S = 0.001


def _sample_times(rate_hz: float, duration_s: float) -> list[float]:
    clock = SampleClock(rate_hz)
    return [k * DT_S for k in range(round(duration_s / DT_S)) if clock.due(k * DT_S)]


@pytest.mark.parametrize('rate_hz', [500.0, 120.0, 1000.0, 30.0])
def test_sample_clocks_keep_their_long_run_rate_on_a_1_ms_grid(rate_hz):
    times = _sample_times(rate_hz, 10.0)
    assert len(times) == pytest.approx(rate_hz * 10.0, abs=1)
    gaps = np.diff(times)
    assert gaps.max() <= 1.0 / rate_hz + DT_S + 1e-9


def test_a_sample_clock_skips_instants_missed_while_not_asked():
    clock = SampleClock(100.0)
    assert clock.due(0.0)
    assert clock.due(0.5)  # 49 instants passed unasked: one sample, not a burst
    assert not clock.due(0.505)
    assert clock.due(0.51)


def test_perfect_sensors_by_default():
    rng = np.random.default_rng(0)
    config = SensingConfig()
    camera = BallCamera(config, rng)
    camera.observe(1.0, np.array([1.0, 2.0, 3.0]), np.array([4.0, 5.0, 6.0]))
    (observation,) = camera.delivered(1.0)
    assert observation.stamp_s == 1.0
    np.testing.assert_array_equal(observation.position_m, [1.0, 2.0, 3.0])
    np.testing.assert_array_equal(observation.velocity_m_s, [4.0, 5.0, 6.0])
    force, torque = ForceTorqueSensor(config, rng).measure(np.array([1.0, 2.0, 3.0]), np.array([0.1, 0.2, 0.3]))
    np.testing.assert_array_equal(force, [1.0, 2.0, 3.0])
    np.testing.assert_array_equal(torque, [0.1, 0.2, 0.3])


def test_camera_latency_dropout_and_noise():
    config = SensingConfig(
        ball_position_noise_std_m=0.004,
        ball_velocity_noise_std_m_s=0.1,
        ball_latency_s=0.025,
        ball_dropout_probability=0.2,
    )
    camera = BallCamera(config, np.random.default_rng(1))
    truth = np.array([-1.0, 0.2, 1.0])
    stamps = [k / 120.0 for k in range(2000)]
    for stamp in stamps:
        camera.observe(stamp, truth, np.zeros(3))
    assert camera.delivered(stamps[0] + 0.024) == []
    delivered = camera.delivered(stamps[-1] + 0.025)
    assert len(delivered) / len(stamps) == pytest.approx(0.8, abs=0.03)
    errors = np.array([o.position_m - truth for o in delivered])
    assert errors.std() == pytest.approx(0.004, rel=0.1)
    assert abs(errors.mean()) < 0.0005


def test_force_torque_bias_and_noise():
    config = SensingConfig(
        ft_force_noise_std_n=0.3,
        ft_torque_noise_std_nm=0.02,
        ft_force_bias_n=(1.5, -2.0, 3.0),
        ft_torque_bias_nm=(0.05, -0.03, 0.08),
    )
    sensor = ForceTorqueSensor(config, np.random.default_rng(2))
    readings = [sensor.measure(np.zeros(3), np.zeros(3)) for _ in range(5000)]
    forces = np.array([f for f, _ in readings])
    torques = np.array([t for _, t in readings])
    np.testing.assert_allclose(forces.mean(axis=0), [1.5, -2.0, 3.0], atol=0.03)
    np.testing.assert_allclose(torques.mean(axis=0), [0.05, -0.03, 0.08], atol=0.002)
    assert forces.std(axis=0) == pytest.approx([0.3] * 3, rel=0.1)


@pytest.mark.parametrize(
    'bad',
    [
        dict(ball_latency_s=-0.1),
        dict(ball_dropout_probability=1.0),
        dict(ft_force_noise_std_n=float('nan')),
        dict(ft_force_bias_n=(1.0, 2.0)),
    ],
)
def test_bad_sensing_levels_are_rejected(bad):
    with pytest.raises(ValueError):
        SensingConfig(**bad)
