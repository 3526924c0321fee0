"""DTW convention and smoothness measures (stylepong_policy.evaluation.style_metrics)."""

import numpy as np
import pytest

from stylepong_policy.evaluation import style_metrics
from stylepong_policy.training.dataset import Clip, SourceClip, assemble_dataset


def reference_dtw(a: np.ndarray, b: np.ndarray) -> float:
    """The convention written out: Euclidean local cost, steps (1,1), (1,0), (0,1) each adding it once."""
    cost = np.linalg.norm(a[:, None, :] - b[None, :, :], axis=2)
    total = np.full((len(a) + 1, len(b) + 1), np.inf)
    total[0, 0] = 0.0
    for i in range(1, len(a) + 1):
        for j in range(1, len(b) + 1):
            total[i, j] = cost[i - 1, j - 1] + min(total[i - 1, j - 1], total[i - 1, j], total[i, j - 1])
    return float(total[-1, -1])


def test_hand_computed_example():
    # Local costs |a_i - b_j|: a0-b0 = a0-b1 = 5, a1-b0 = a1-b1 = 10. Diagonal path: 5 + 10 = 15.
    # (sqrt of summed squares would give 11.18; a diagonal step weighted twice, 20.)
    a = np.array([[3.0, 4.0], [6.0, 8.0]])
    b = np.zeros((2, 2))
    assert style_metrics.dtw_distance_rad(a, b) == pytest.approx(15.0, abs=1e-12)
    distance, path = style_metrics.dtw_path(a, b)
    assert distance == pytest.approx(15.0, abs=1e-12) and path == [(0, 0), (1, 1)]


def test_not_normalised_and_one_sided_repeats_add_their_cost():
    a = np.tile([[3.0, 4.0]], (3, 1))
    b = np.zeros((1, 2))
    assert style_metrics.dtw_distance_rad(a, b) == pytest.approx(15.0)  # 3 frames x 5
    distance, path = style_metrics.dtw_path(a, b)
    assert path == [(0, 0), (1, 0), (2, 0)]


def test_identical_and_time_warped_copies_are_at_zero():
    t = np.linspace(0.0, 1.0, 40)
    q = np.stack([np.sin(3 * t), t**2, np.cos(t)], axis=1)
    assert style_metrics.dtw_distance_rad(q, q) == 0.0
    assert style_metrics.dtw_distance_rad(q, np.repeat(q, 2, axis=0)) == 0.0


def test_matches_the_convention_on_random_sequences():
    rng = np.random.default_rng(3)
    for _ in range(5):
        a = rng.normal(size=(int(rng.integers(2, 30)), 6))
        b = rng.normal(size=(int(rng.integers(2, 30)), 6))
        assert style_metrics.dtw_distance_rad(a, b) == pytest.approx(reference_dtw(a, b), rel=1e-12)
        distance, path = style_metrics.dtw_path(a, b)
        assert distance == pytest.approx(reference_dtw(a, b), rel=1e-12)
        # The path is a valid warping path whose costs add up to the distance.
        assert path[0] == (0, 0) and path[-1] == (len(a) - 1, len(b) - 1)
        steps = np.diff(np.array(path), axis=0)
        assert set(map(tuple, steps)) <= {(1, 1), (1, 0), (0, 1)}
        assert sum(np.linalg.norm(a[i] - b[j]) for i, j in path) == pytest.approx(distance, rel=1e-12)


def test_nearest_reference_takes_the_smallest_and_its_path_length():
    stroke = np.zeros((4, 6))
    far, near = np.full((3, 6), 1.0), np.full((5, 6), 0.1)
    match = style_metrics.nearest_reference(stroke, [(7, far), (9, near)])
    assert match.clip == 9
    assert match.distance == pytest.approx(5 * np.sqrt(6) * 0.1)
    assert match.path_length == 5 and match.distance_per_step == pytest.approx(np.sqrt(6) * 0.1)


def test_reference_clips_of_a_label_include_every_speed_factor():
    q = np.linspace(0, 1, 30)[:, None] * np.ones((1, 6))
    clip = Clip(t=np.arange(30) / 60.0, q=q, qd=np.ones_like(q))
    dataset = assemble_dataset(
        [SourceClip(clip, 'forward', 'a'), SourceClip(clip, 'leftward', 'b')], (2, 3), [f'j{i}' for i in range(6)], 60.0
    )
    clips = style_metrics.reference_clips(dataset, 'forward')
    assert [len(c) for _, c in clips] == [30, 15, 10]


def test_smoothness_of_a_cubic_is_exact():
    rate_hz = 60.0
    h = 1.0 / rate_hz
    t = np.arange(61) * h  # 0 .. 1 s
    c = np.array([1.0, -2.0, 0.5, 0.0, 3.0, -0.25])  # q_j = c_j t^3
    q = t[:, None] ** 3 * c[None, :]
    s = style_metrics.smoothness(q, rate_hz)
    cmax = np.abs(c).max()
    # Backward differences of a cubic: speed c (3t^2 - 3th + h^2), acceleration 6c(t - h), jerk 6c.
    assert s.peak_joint_speed_rad_s == pytest.approx(cmax * (3 - 3 * h + h * h), rel=1e-9)
    assert s.peak_joint_acceleration_rad_s2 == pytest.approx(6 * cmax * (1 - h), rel=1e-9)
    assert s.mean_abs_jerk_rad_s3 == pytest.approx(6 * np.abs(c).mean(), rel=1e-6)


def test_smoothness_of_a_sine_is_near_its_derivatives():
    rate_hz, amplitude, omega = 60.0, 0.4, 2 * np.pi * 1.5
    t = np.arange(0, 2.0, 1.0 / rate_hz)
    q = np.stack([amplitude * np.sin(omega * t)] + [np.zeros_like(t)] * 5, axis=1)
    s = style_metrics.smoothness(q, rate_hz)
    assert s.peak_joint_speed_rad_s == pytest.approx(amplitude * omega, rel=0.01)
    assert s.peak_joint_acceleration_rad_s2 == pytest.approx(amplitude * omega**2, rel=0.02)
    # |jerk| = A w^3 |cos|, mean over a whole number of periods 2/pi A w^3, over one joint in six.
    assert s.mean_abs_jerk_rad_s3 == pytest.approx(2 / np.pi * amplitude * omega**3 / 6, rel=0.03)


def test_smoothness_needs_four_frames():
    with pytest.raises(ValueError):
        style_metrics.smoothness(np.zeros((3, 6)), 60.0)
    assert style_metrics.mean_smoothness([]) is None


def test_cost_breakdown_adds_up_to_the_distance_by_joint_and_by_phase():
    generator = np.random.default_rng(3)
    stroke = np.cumsum(generator.normal(0.0, 0.05, (40, 6)), axis=0)
    clip = np.cumsum(generator.normal(0.0, 0.05, (25, 6)), axis=0)
    distance, path = style_metrics.dtw_path(stroke, clip)
    parts = style_metrics.cost_breakdown(stroke, clip, path, hit_frame=30, rate_hz=60.0)
    assert parts.by_joint_rad.sum() == pytest.approx(distance, rel=1e-12)
    assert sum(parts.by_phase_rad.values()) == pytest.approx(distance, rel=1e-12)
    assert all(value > 0.0 for value in parts.by_phase_rad.values())


def test_cost_breakdown_puts_a_one_joint_difference_on_that_joint_and_phase():
    # The stroke leaves the clip's pose on joint 4 only, and only after its hit at frame 20.
    clip = np.zeros((30, 6))
    stroke = np.zeros((30, 6))
    stroke[20:, 4] = 0.3
    distance, path = style_metrics.dtw_path(stroke, clip)
    parts = style_metrics.cost_breakdown(stroke, clip, path, hit_frame=20, rate_hz=60.0)
    assert distance == pytest.approx(10 * 0.3)
    assert parts.by_joint_rad[4] == pytest.approx(distance) and np.delete(parts.by_joint_rad, 4).sum() == 0.0
    assert parts.by_phase_rad == pytest.approx({'waiting': 0.0, 'swing': 0.0, 'follow_through': distance})


def test_stroke_phases_without_a_hit_end_in_the_swing():
    # 60 Hz: the swing is the last 15 frames before the hit (or before the end without one).
    assert style_metrics.stroke_phases(40, hit_frame=30, rate_hz=60.0).tolist() == [0] * 15 + [1] * 15 + [2] * 10
    assert style_metrics.stroke_phases(40, hit_frame=-1, rate_hz=60.0).tolist() == [0] * 25 + [1] * 15
