"""Stroke directions from ball tracks, and the stroke file (stylepong_policy.evaluation.strokes)."""

import numpy as np
import pytest

from stylepong_policy.evaluation import strokes
from stylepong_sim import world_spec
from stylepong_sim.teaching import teacher

RATE_HZ = 60.0
PHYSICS_DT_S = 0.001


def served_track(target_y_m: float, speed_xy_m_s: float = 5.0, vz_m_s: float = 1.0):
    """A ball launched over the opponent's half towards (plane x, target_y), flying with gravity and drag
    at 1 ms, bouncing on the table, sampled at 60 Hz: (positions [T, 3], velocities [T, 3], fine
    positions [K, 3] at 1 ms)."""
    plane_x = strokes.paddle_home_position_m()[0]
    start = np.array([1.2, -0.3, 1.0])
    heading = np.array([plane_x, target_y_m]) - start[:2]
    heading /= np.linalg.norm(heading)
    p = start.copy()
    v = np.array([heading[0] * speed_xy_m_s, heading[1] * speed_xy_m_s, vz_m_s])
    gravity = np.array([0.0, 0.0, -world_spec.GRAVITY_M_S2])
    contact_z = world_spec.TABLE_CONTACT_HEIGHT_M
    fine_p, fine_v = [p.copy()], [v.copy()]
    while p[0] > plane_x - 0.5:
        v = v + (gravity + world_spec.drag_acceleration(v)) * PHYSICS_DT_S
        p = p + v * PHYSICS_DT_S
        if p[2] < contact_z and v[2] < 0 and world_spec.on_table(p[0], p[1]):
            p[2] = contact_z
            v = world_spec.contact_response(
                v, np.array([0.0, 0.0, 1.0]), world_spec.TABLE_RESTITUTION, world_spec.TABLE_TANGENTIAL_FACTOR
            )
        fine_p.append(p.copy())
        fine_v.append(v.copy())
    fine_p, fine_v = np.array(fine_p), np.array(fine_v)
    every = int(round(1.0 / (RATE_HZ * PHYSICS_DT_S)))
    return fine_p[::every], fine_v[::every], fine_p


def fine_crossing_y(fine_p: np.ndarray) -> float:
    plane_x = strokes.paddle_home_position_m()[0]
    i = int(np.flatnonzero(fine_p[:, 0] <= plane_x)[0])
    fraction = (fine_p[i - 1, 0] - plane_x) / (fine_p[i - 1, 0] - fine_p[i, 0])
    return float(fine_p[i - 1, 1] + fraction * (fine_p[i, 1] - fine_p[i - 1, 1]))


def test_the_synthetic_track_bounces_on_the_robots_half_before_the_plane():
    positions, velocities, fine = served_track(0.1)
    bounce = int(np.flatnonzero((velocities[:-1, 2] < 0) & (velocities[1:, 2] > 0))[0])
    assert -1.37 < positions[bounce, 0] < 0.0
    assert positions[bounce, 0] > strokes.paddle_home_position_m()[0]


@pytest.mark.parametrize('target_y_m', [-0.5, 0.0, 0.1, 0.35])
def test_untouched_track_crossing_is_interpolated_where_the_ball_crosses(target_y_m):
    positions, velocities, fine = served_track(target_y_m)
    y = strokes.arrival_y_m(positions, velocities, len(positions))
    assert y == pytest.approx(fine_crossing_y(fine), abs=1e-6)
    assert y == pytest.approx(target_y_m, abs=1e-6)


def test_track_cut_by_a_hit_before_the_plane_is_extrapolated_along_its_heading():
    positions, velocities, fine = served_track(0.3)
    plane_x = strokes.paddle_home_position_m()[0]
    before_plane = int(np.flatnonzero(positions[:, 0] > plane_x + 0.15)[-1])
    # After the hit the ball flies back: those samples must not count.
    hit_positions = positions.copy()
    hit_positions[before_plane:, 0] = positions[before_plane, 0] + np.arange(len(positions) - before_plane) * 0.08
    y = strokes.arrival_y_m(hit_positions, velocities, before_plane)
    assert y == pytest.approx(fine_crossing_y(fine), abs=1e-6)
    # Cut before the bounce as well: the table scales both horizontal components alike.
    assert strokes.arrival_y_m(positions, velocities, 5) == pytest.approx(fine_crossing_y(fine), abs=1e-6)


@pytest.mark.parametrize(
    'offset_m, expected',
    [
        (0.0, 'forward'),
        (0.079, 'forward'),
        (0.081, 'leftward'),
        (0.4, 'leftward'),
        (-0.089, 'forward'),
        (-0.091, 'rightward'),
        (-0.6, 'rightward'),
    ],
)
def test_direction_thresholds_around_the_paddles_home_y(offset_m, expected):
    home_y = strokes.paddle_home_position_m()[1]
    assert strokes.direction_of(home_y + offset_m) == expected


def test_synthetic_balls_get_the_direction_of_where_they_arrive():
    home_y = strokes.paddle_home_position_m()[1]
    for offset_m, expected in ((0.0, 'forward'), (0.3, 'leftward'), (-0.3, 'rightward')):
        positions, velocities, _ = served_track(home_y + offset_m)
        assert strokes.direction_of(strokes.arrival_y_m(positions, velocities, len(positions))) == expected


def test_thresholds_agree_with_the_demonstrations_hitting_points():
    assert strokes.DIRECTIONS == teacher.SWINGS
    home_y = strokes.paddle_home_position_m()[1]
    for label, shape in teacher.STROKES.items():
        assert strokes.direction_of(home_y + shape.hit_offset_m[1]) == label
    # Halfway between neighbouring hitting points.
    hits = {label: shape.hit_offset_m[1] for label, shape in teacher.STROKES.items()}
    assert strokes.LEFTWARD_ABOVE_M == pytest.approx((hits['forward'] + hits['leftward']) / 2)
    assert strokes.RIGHTWARD_BELOW_M == pytest.approx((hits['forward'] + hits['rightward']) / 2)


def test_paddle_home_matches_the_world_spec():
    x, y, z = strokes.paddle_home_position_m()
    assert (x, y, z) == pytest.approx((-1.47, 0.11, 0.89), abs=0.01)  # world_spec's stated home


def test_stroke_ends_after_the_follow_through_or_at_the_verdict():
    assert strokes.stroke_end_frame(verdict_frame=80, hit_frame=40, rate_hz=60.0) == 58
    assert strokes.stroke_end_frame(verdict_frame=50, hit_frame=40, rate_hz=60.0) == 50
    assert strokes.stroke_end_frame(verdict_frame=70, hit_frame=strokes.NO_FRAME, rate_hz=60.0) == 70


def _stroke(seed, ball, frames, direction, success):
    rng = np.random.default_rng(seed * 100 + ball)
    return strokes.Stroke(
        seed=seed,
        ball=ball,
        joint_positions_rad=rng.normal(size=(frames, 6)).astype(np.float32),
        ball_position_m=rng.normal(size=(frames, 3)).astype(np.float32),
        direction=direction,
        arrival_y_m=0.25,
        launch_velocity_m_s=np.array([-5.0, 0.3, 1.0]),
        outcome='returned' if success else 'net',
        success=success,
        hit=True,
        hit_frame=frames - 19,
        verdict_frame=frames + 10,
    )


def test_stroke_file_round_trip(tmp_path):
    written = [_stroke(1000, 0, 40, 'forward', True), _stroke(1000, 1, 55, 'rightward', False)]
    path = strokes.save_strokes(
        tmp_path / 'strokes.npz',
        written,
        rate_hz=60.0,
        joint_names=[f'j{i}' for i in range(6)],
        actor='models/a.pt',
        speed='all',
    )
    loaded = strokes.load_strokes(path)
    assert loaded.rate_hz == 60.0 and loaded.actor == 'models/a.pt' and loaded.speed == 'all'
    assert loaded.joint_names == tuple(f'j{i}' for i in range(6))
    assert (loaded.plane_x_m, loaded.paddle_home_y_m) == pytest.approx(strokes.paddle_home_position_m()[:2])
    for original, back in zip(written, loaded.strokes):
        np.testing.assert_array_equal(original.joint_positions_rad, back.joint_positions_rad)
        np.testing.assert_array_equal(original.ball_position_m, back.ball_position_m)
        for name in (
            'seed',
            'ball',
            'direction',
            'arrival_y_m',
            'outcome',
            'success',
            'hit',
            'hit_frame',
            'verdict_frame',
            'launch_speed_m_s',
        ):
            assert getattr(original, name) == getattr(back, name), name
    with np.load(path) as data:
        assert list(data['stroke_length']) == [40, 55] and list(data['stroke_start']) == [0, 40]
        assert data['q_rad'].shape == (95, 6) and data['launch_velocity_m_s'].shape == (2, 3)
