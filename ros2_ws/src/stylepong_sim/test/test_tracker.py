"""The simulated ball tracker: positions in its camera frame, stamped at exposure, with the configured
latency, noise, lost frames and false detections."""

import numpy as np
import pytest

from stylepong_sim.cells.tracker import BallTracker, TrackerConfig, camera_to_world, world_to_camera

BALL = np.array([-0.5, 0.2, 1.0])
PERFECT = TrackerConfig()
# Every imperfection at once: a jittered latency, position noise, lost frames and false detections.
IMPERFECT = TrackerConfig(
    latency_s=0.02,
    latency_jitter_s=0.005,
    position_noise_std_m=0.003,
    dropout_probability=0.1,
    outlier_probability=0.05,
)


def test_camera_and_world_frames_are_inverse_and_the_camera_looks_at_the_table():
    config = PERFECT
    np.testing.assert_allclose(camera_to_world(config, world_to_camera(config, BALL)), BALL, atol=1e-12)
    centre = world_to_camera(config, (0.0, 0.0, 0.76))
    assert centre[0] > 2.0 and np.hypot(centre[1], centre[2]) < 0.3 * centre[0]  # x is the line of sight


def test_a_perfect_tracker_reports_the_ball_at_once_in_its_frame():
    config = PERFECT
    tracker = BallTracker(config, np.random.default_rng(0))
    tracker.expose(1.0, BALL)
    (detection,) = tracker.delivered(1.0)
    assert detection.stamp_s == 1.0
    np.testing.assert_allclose(camera_to_world(config, detection.position_camera_m), BALL, atol=1e-12)
    tracker.expose(1.01, None)
    assert tracker.delivered(2.0) == []  # no ball, no false detections: nothing


def test_latency_noise_losses_and_false_detections_at_their_rates():
    config = IMPERFECT
    tracker = BallTracker(config, np.random.default_rng(1))
    frames = 6000
    delivered = []
    for k in range(frames):
        t = k / 150.0
        tracker.expose(t, BALL)
        delivered += [(t, d) for d in tracker.delivered(t)]
    delays = np.array([t - d.stamp_s for t, d in delivered])
    assert delays.min() >= 0.015 - 1e-9 and delays.max() <= 0.025 + 1 / 150.0
    stamps = [d.stamp_s for _, d in delivered]
    assert stamps == sorted(stamps)  # in exposure order
    errors = np.array([np.linalg.norm(camera_to_world(config, d.position_camera_m) - BALL) for _, d in delivered])
    ball, false = errors[errors < 0.05], errors[errors >= 0.05]
    assert np.std(ball) == pytest.approx(0.003 * np.sqrt(3 - 8 / np.pi), rel=0.1)  # Maxwell spread of 3-D noise
    assert len(ball) / frames == pytest.approx(0.9, abs=0.02)
    assert len(false) / frames == pytest.approx(0.05, abs=0.01)


def test_bad_settings_are_refused_with_the_parameter_named():
    with pytest.raises(ValueError, match='ball_detection_rate_hz'):
        TrackerConfig(rate_hz=0.0)
    with pytest.raises(ValueError, match='latency_jitter'):
        TrackerConfig(latency_s=0.01, latency_jitter_s=0.02)
    with pytest.raises(ValueError, match='outlier_probability'):
        TrackerConfig(outlier_probability=1.0)
