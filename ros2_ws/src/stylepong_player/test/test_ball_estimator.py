"""The ball estimator's filter and track rules on made-up flights (no ROS, no simulator): what it publishes,
what it refuses and why, and how it recovers."""

import math

import numpy as np
import pytest

from stylepong_description import robot_cell
from stylepong_player.ball_estimator import BallEstimator, EstimatorConfig, Outcome
from stylepong_player.ball_prediction import predict_ball

FRAME_S = 1.0 / 150.0
NOISE_M = 0.003


def flight(p0, v0, frames: int, start_s: float = 1.0):
    """(stamp, true position, true velocity) per tracker frame of the flight model's ball."""
    p, v = np.array(p0, dtype=float), np.array(v0, dtype=float)
    out = []
    for k in range(frames):
        out.append((start_s + k * FRAME_S, p.copy(), v.copy()))
        p, v = predict_ball(p, v, FRAME_S)
    return out


INCOMING = dict(p0=(1.2, 0.1, 1.0), v0=(-5.5, -0.2, 0.3))  # bounces on the robot's half about 0.25 s later


def feed(estimator, samples, rng, noise_m: float = NOISE_M):
    return [estimator.update(t, p + rng.normal(0.0, noise_m, 3)) for t, p, _ in samples]


def test_a_new_ball_is_published_once_confirmed_with_its_velocity_and_a_covariance():
    estimator, rng = BallEstimator(), np.random.default_rng(0)
    samples = flight(**INCOMING, frames=60)
    results = feed(estimator, samples, rng)
    first = next(i for i, r in enumerate(results) if r.outcome == Outcome.PUBLISHED)
    assert first == EstimatorConfig().confirm_detections - 1
    assert all(r.outcome == Outcome.TENTATIVE for r in results[:first])
    assert all(r.outcome == Outcome.PUBLISHED for r in results[first:])
    last, (t, _, v) = results[-1].estimate, samples[-1]
    assert last.stamp_s == t and np.linalg.norm(last.velocity_m_s - v) < 0.15
    assert last.covariance.shape == (6, 6) and 0.0 < last.velocity_std_m_s < 0.2
    assert results[first].estimate.velocity_std_m_s > last.velocity_std_m_s


def test_the_velocity_is_right_50_ms_after_a_bounce_on_the_table():
    rng = np.random.default_rng(1)
    errors = []
    for k in range(20):
        estimator = BallEstimator()
        samples = flight((1.2, 0.1 * (k % 5 - 2), 1.0), (-5.0 - 0.1 * k, 0.0, 0.5), frames=120)
        bounce = next(i for i, (_, _, v) in enumerate(samples[1:], 1) if v[2] > 0 > samples[i - 1][2][2])
        results = feed(estimator, samples, rng)
        after = bounce + math.ceil(0.05 / FRAME_S)
        assert results[after].outcome == Outcome.PUBLISHED
        errors.append(np.linalg.norm(results[after].estimate.velocity_m_s - samples[after][2]))
    assert np.percentile(errors, 95) < 0.3, errors


@pytest.mark.parametrize(
    'position, kind',
    [
        ((math.nan, 0.0, 1.0), 'not_finite'),
        ((math.inf, 0.0, 1.0), 'not_finite'),
        ((30.0, 0.0, 1.0), 'outside'),
        ((0.0, 0.0, -0.5), 'outside'),
        ((robot_cell.ROBOT_BASE_POSITION_M[0] - 0.3, 0.0, 1.0), 'behind_robot'),
    ],
)
def test_bad_detections_are_refused_and_named(position, kind):
    estimator = BallEstimator()
    result = estimator.update(1.0, position)
    assert result.outcome == Outcome.REJECTED and result.kind == kind and result.reason
    assert estimator.update(2.0, INCOMING['p0']).outcome == Outcome.TENTATIVE  # nothing was disturbed


def test_a_teleporting_detection_and_a_second_ball_do_not_move_the_track():
    estimator, rng = BallEstimator(), np.random.default_rng(2)
    samples = flight(**INCOMING, frames=40)
    feed(estimator, samples[:20], rng)
    assert estimator.confirmed
    # A jump of half a metre in one frame (a false detection) is refused.
    t, p, _ = samples[20]
    jump = estimator.update(t, p + np.array([0.0, 0.5, 0.0]))
    assert jump.outcome == Outcome.REJECTED and jump.kind == 'gated' and 'sigma' in jump.reason
    # A second ball in every frame beside the first: the first keeps its track.
    other = flight((1.0, -0.6, 1.2), (-4.0, 0.5, 0.0), frames=20, start_s=samples[20][0])
    for (t, p, v), (_, q, _) in zip(samples[20:], other):
        published = estimator.update(t, p + rng.normal(0.0, NOISE_M, 3))
        assert estimator.update(t, q).outcome == Outcome.REJECTED
        assert published.outcome == Outcome.PUBLISHED and np.linalg.norm(published.estimate.position_m - p) < 0.02


def test_detections_with_a_stamp_from_the_past_are_refused():
    estimator = BallEstimator()
    estimator.update(1.0, INCOMING['p0'])
    result = estimator.update(0.9, INCOMING['p0'])
    assert result.outcome == Outcome.REJECTED and result.kind == 'stamp_order'


def test_after_the_tracker_stops_for_half_a_second_the_next_ball_is_a_new_track():
    estimator, rng = BallEstimator(), np.random.default_rng(3)
    feed(estimator, flight(**INCOMING, frames=20), rng)
    assert estimator.confirmed
    started = estimator.tracks_started
    # The tracker is silent for 0.5 s, then a different ball comes: nothing is published until it is confirmed.
    results = feed(
        estimator, flight((1.0, -0.3, 1.1), (-6.0, 0.3, 0.0), frames=10, start_s=1.0 + 20 * FRAME_S + 0.5), rng
    )
    assert estimator.tracks_started == started + 1
    assert [r.outcome for r in results[:3]] == [Outcome.TENTATIVE] * 3
    assert results[3].outcome == Outcome.PUBLISHED and results[3].estimate.velocity_m_s[0] < -5.0


def test_a_ball_hit_back_by_the_paddle_is_followed_within_a_few_frames():
    estimator, rng = BallEstimator(), np.random.default_rng(4)
    incoming = flight((-0.4, 0.0, 1.0), (-5.0, 0.0, 0.0), frames=30)
    feed(estimator, incoming, rng)
    t_hit, p_hit, _ = incoming[-1]
    returned = flight(p_hit, (6.0, 0.3, 2.0), frames=12, start_s=t_hit + FRAME_S)
    results = feed(estimator, returned, rng)
    followed = [i for i, r in enumerate(results) if r.outcome == Outcome.PUBLISHED]
    # The track refuses the new course until the candidate built from it is confirmed, then follows it.
    assert followed and followed[0] <= EstimatorConfig().confirm_detections
    assert followed == list(range(followed[0], len(results)))
    assert np.linalg.norm(results[-1].estimate.velocity_m_s - returned[-1][2]) < 0.5


def test_a_track_started_on_a_false_detection_is_dropped_for_the_ball():
    estimator, rng = BallEstimator(), np.random.default_rng(5)
    samples = flight(**INCOMING, frames=10)
    assert estimator.update(samples[0][0] - FRAME_S, (0.0, 1.5, 0.5)).outcome == Outcome.TENTATIVE  # a light
    results = feed(estimator, samples, rng)
    assert results[EstimatorConfig().confirm_detections - 1].outcome == Outcome.PUBLISHED


def test_config_refuses_nonsense():
    with pytest.raises(ValueError, match='gate_sigma'):
        BallEstimator(EstimatorConfig(gate_sigma=-1.0))
    with pytest.raises(ValueError, match='confirm_detections'):
        BallEstimator(EstimatorConfig(confirm_detections=1))
    with pytest.raises(ValueError, match='play volume'):
        BallEstimator(EstimatorConfig(play_volume_min_m=(0.0, 0.0, 3.0)))
