"""The ball carried forward over its age: flight, the bounce on the table, a ball beside the table."""

import math

import numpy as np
import pytest

from stylepong_description import robot_cell
from stylepong_player.ball_prediction import predict_ball

CONTACT_Z_M = robot_cell.TABLE_CONTACT_HEIGHT_M


def test_no_time_no_change():
    p, v = predict_ball([-1.0, 0.1, 1.0], [5.0, 0.2, -1.0], 0.0)
    assert p.tolist() == [-1.0, 0.1, 1.0] and v.tolist() == [5.0, 0.2, -1.0]


def test_a_negative_age_is_no_time():
    p, _ = predict_ball([-1.0, 0.1, 1.0], [5.0, 0.2, -1.0], -0.01)
    assert p.tolist() == [-1.0, 0.1, 1.0]


def test_flight_is_a_parabola_slowed_by_drag():
    """Over 40 ms a 6 m/s ball falls by g t^2 / 2 and loses k v^2 t of its speed, each within a millimetre
    (or a centimetre per second)."""
    t_s, speed = 0.04, 6.0
    p, v = predict_ball([-0.5, 0.0, 1.2], [-speed, 0.0, 0.0], t_s)
    g = robot_cell.GRAVITY_M_S2
    assert p[2] == pytest.approx(1.2 - 0.5 * g * t_s**2, abs=1e-3)
    assert v[2] == pytest.approx(-g * t_s, abs=0.01)
    drag_m_s2 = robot_cell.DRAG_K_PER_M * speed**2
    assert v[0] == pytest.approx(-speed + drag_m_s2 * t_s, abs=0.01)
    assert p[0] == pytest.approx(-0.5 - speed * t_s + 0.5 * drag_m_s2 * t_s**2, abs=1e-3)


def test_a_ball_dropped_on_the_table_bounces_with_its_restitution():
    """Dropped from 2 cm above contact, it meets the table after sqrt(2 h / g) and leaves at e times its
    speed of impact, its horizontal speed scaled by the tangential factor."""
    g = robot_cell.GRAVITY_M_S2
    drop_m = 0.02
    impact_s = math.sqrt(2.0 * drop_m / g)
    impact_speed = g * impact_s
    p, v = predict_ball([-0.8, 0.2, CONTACT_Z_M + drop_m], [1.0, 0.0, 0.0], impact_s + 0.01)
    assert v[2] == pytest.approx(robot_cell.TABLE_RESTITUTION * impact_speed - g * 0.01, abs=0.03)
    assert v[0] == pytest.approx(robot_cell.TABLE_TANGENTIAL_FACTOR, abs=0.02)
    assert p[2] > CONTACT_Z_M


def test_a_ball_beside_the_table_falls_past_it():
    y_m = robot_cell.HALF_WIDTH_M + 0.1
    p, v = predict_ball([-0.8, y_m, CONTACT_Z_M + 0.02], [0.0, 0.0, 0.0], 0.2)
    assert v[2] < 0.0 and p[2] < CONTACT_Z_M - 0.1


def test_two_short_predictions_make_one_long_one():
    start = ([1.0, -0.2, 1.1], [-6.0, 0.5, -2.0])
    p1, v1 = predict_ball(*start, 0.03)
    p2, v2 = predict_ball(p1, v1, 0.05)
    p, v = predict_ball(*start, 0.08)
    np.testing.assert_allclose(p2, p, atol=1e-9)
    np.testing.assert_allclose(v2, v, atol=1e-9)
