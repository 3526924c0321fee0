"""The calibration command's measuring pieces: a throw reaches its target, crossings interpolate, a return is
read after the hit, the summary compares against the MuJoCo cell, and a step response is measured."""

import math

import numpy as np
import pytest

from stylepong_sim import world_spec
from stylepong_sim.cells import ur_servoj
from stylepong_sim.nodes import calibration


def test_an_aimed_throw_reaches_its_target_with_drag():
    target = np.array([-1.45, 0.1, 0.9])
    direction = np.array([0.9, 0.0, 0.4359])
    start, velocity = calibration.aimed_throw(target, direction, 5.0, 0.15)
    assert calibration._fly(start, velocity, 0.15) == pytest.approx(target, abs=1e-4)
    assert np.dot(velocity, direction) < 0.0


def test_crossing_and_return_read_the_60_hz_trace():
    trace = calibration.BallTrace(
        times_s=[0.1, 0.2, 0.3],
        positions_m=[np.array([-1.0, 0.1, 1.0]), np.array([-1.4, 0.3, 0.8]), np.array([-1.0, 0.3, 0.9])],
        velocities_m_s=[np.array([-4.0, 2.0, -2.0]), np.array([-4.0, 0.0, -2.0]), np.array([4.0, 0.0, 4.0])],
        hit_time_s=0.25,
        landing_m=np.array([0.5, 0.2, 0.78]),
    )
    y, z, speed = calibration.crossing(trace, -1.2)
    assert (y, z) == pytest.approx((0.2, 0.9))
    assert speed == pytest.approx(math.hypot(4.0, 1.0, 2.0))
    returned = calibration.return_after_hit(trace)
    assert returned['elevation_deg'] == pytest.approx(45.0)
    assert returned['heading_deg'] == pytest.approx(0.0)
    assert returned['landing_xy_m'] == pytest.approx([0.5, 0.2])


def test_the_ball_summary_measures_against_the_mujoco_cell():
    row = {
        'seed': 1,
        'mujoco': {'bounce_xy_m': [-0.5, 0.0], 'crossing_y_z_speed': (0.1, 0.9, 5.0)},
        'batched': {'bounce_xy_m': [-0.503, 0.004], 'crossing_y_z_speed': (0.1, 0.91, 5.1)},
        'pybullet': {'bounce_xy_m': [-0.5, 0.0], 'crossing_y_z_speed': None},
    }
    summary = calibration.summarise_ball([row])
    assert summary['batched']['bounce_mm_max'] == pytest.approx(5.0)
    assert summary['batched']['crossing_z_mm_max'] == pytest.approx(10.0)
    assert summary['pybullet']['crossings_compared'] == 0


def test_servoj_lags_a_ramp_more_than_its_look_ahead():
    soft = calibration.step_response('mujoco', ur_servoj.UR_SERVOJ, ur_servoj.ServojSettings(125.0, 0.1, 300.0))
    assert soft['ramp_lag_ms'] > 100.0
    assert soft['shoulder_pan']['overshoot_pct'] < 1.0
    assert world_spec.PHYSICS_DT_S * 1e3 < soft['shoulder_pan']['delay_10_ms']
