"""Recording -> 60 Hz clips -> augmentation -> .npz -> discriminator windows (stylepong_policy.training.dataset)."""

import math
import pathlib

import numpy as np
import pytest

from stylepong_policy.training.dataset import (
    PER_CLIP_FIELDS,
    Clip,
    ClipOptions,
    ReferenceDataset,
    SourceClip,
    assemble_dataset,
    discriminator_windows,
    hit_frame,
    make_clips,
    parse_speedups,
    speed_up,
)
from stylepong_recording.joint_state_bags import EPOCH_NS, Swing, wrap_to_pi

NPZ_KEYS = {'t', 'q', 'qd', 'clip_start', 'clip_length', 'label', 'speed_factor', 'source', 'rate_hz', 'joint_names'}
JOINTS = ('a', 'b', 'c', 'd', 'e', 'f')


def sample(motion, rate_hz, duration_s, *, with_velocity=True):
    stamps = EPOCH_NS + np.round(np.arange(int(round(duration_s * rate_hz)) + 1) / rate_hz * 1e9).astype(np.int64)
    q, qd = motion((stamps - stamps[0]) / 1e9)
    velocity = qd if with_velocity else np.full_like(q, np.nan)
    return stamps, stamps + 400_000, q, velocity


def truth_at(motion, t_s):
    return motion(np.asarray(t_s) - EPOCH_NS / 1e9)


def test_clip_is_on_the_rate_grid_inside_the_recording_and_equals_the_motion():
    swing = Swing()
    stamps, receive, q, qd = sample(swing, 500.0, swing.total_s)
    result = make_clips(stamps, receive, q, qd, ClipOptions(idle_speed_rad_s=0.0))
    (clip,) = result.clips
    assert clip.time_source == 'header' and clip.velocity_source == 'bag'
    assert np.allclose(np.diff(clip.t), 1 / 60, rtol=0, atol=1e-5)
    assert clip.t[0] >= stamps[0] / 1e9 - 1e-6 and clip.t[-1] <= stamps[-1] / 1e9 + 1e-6
    assert len(clip) == math.floor(swing.total_s * 60) + 1
    q_true, qd_true = truth_at(swing, clip.t)
    assert np.abs(clip.q - q_true).max() < 1e-4
    assert np.abs(clip.qd - qd_true).max() < 1e-3


def test_zero_header_stamps_fall_back_to_receive_time_with_a_warning():
    swing = Swing()
    stamps, receive, q, qd = sample(swing, 200.0, swing.total_s)
    zeroed = stamps.copy()
    zeroed[:] = 0
    result = make_clips(zeroed, receive, q, qd, ClipOptions(idle_speed_rad_s=0.0))
    (clip,) = result.clips
    assert clip.time_source == 'receive'
    assert any('header stamps unusable' in n and 'zero' in n for n in result.notes)
    assert abs(clip.t[0] - receive[0] / 1e9) < 1e-6


def test_header_stamps_that_go_backwards_fall_back_to_receive_time():
    swing = Swing()
    stamps, receive, q, qd = sample(swing, 200.0, swing.total_s)
    stamps = stamps.copy()
    stamps[100] = stamps[98]  # a driver clock step
    result = make_clips(stamps, receive, q, qd, ClipOptions(idle_speed_rad_s=0.0))
    assert result.clips[0].time_source == 'receive'
    assert any('not increasing' in n for n in result.notes)


def test_exact_repeated_messages_are_dropped_without_giving_up_header_stamps():
    swing = Swing()
    stamps, receive, q, qd = sample(swing, 200.0, swing.total_s)
    index = np.sort(np.concatenate([np.arange(len(stamps)), [50, 51, 300]]))
    result = make_clips(
        stamps[index], receive[index] + np.arange(len(index)), q[index], qd[index], ClipOptions(idle_speed_rad_s=0.0)
    )
    assert result.clips[0].time_source == 'header'
    assert any('3 repeated messages' in n for n in result.notes)


def test_a_joint_recorded_wrapped_into_minus_pi_pi_is_made_continuous():
    swing = Swing()  # wrist_3 turns from 2.8 rad past pi to 4.1 rad
    stamps, receive, q, _qd = sample(swing, 125.0, swing.total_s, with_velocity=False)
    wrapped = q.copy()
    wrapped[:, 5] = wrap_to_pi(q[:, 5])
    assert np.abs(np.diff(wrapped[:, 5])).max() > 6.0  # the recording does jump
    result = make_clips(stamps, receive, wrapped, np.full_like(q, np.nan), ClipOptions(idle_speed_rad_s=0.0))
    (clip,) = result.clips
    assert np.abs(np.diff(clip.q[:, 5])).max() < 0.1
    q_true, qd_true = truth_at(swing, clip.t)
    assert np.abs(clip.q - q_true).max() < 1e-3
    assert np.abs(clip.qd - qd_true).max() < 0.1
    assert clip.velocity_source == 'positions'


def test_velocities_that_disagree_with_the_positions_are_replaced():
    swing = Swing()
    stamps, receive, q, qd = sample(swing, 500.0, swing.total_s)
    result = make_clips(stamps, receive, q, np.zeros_like(qd), ClipOptions(idle_speed_rad_s=0.0))
    (clip,) = result.clips
    assert clip.velocity_source == 'positions'
    assert any('disagree' in n for n in result.notes)
    assert np.abs(clip.qd - truth_at(swing, clip.t)[1]).max() < 0.05


def test_idle_lead_in_and_lead_out_are_trimmed_by_the_threshold():
    swing = Swing(rest_before_s=1.0, rest_after_s=2.0)
    stamps, receive, q, qd = sample(swing, 500.0, swing.total_s)
    threshold = 0.05
    (clip,) = make_clips(stamps, receive, q, qd, ClipOptions(idle_speed_rad_s=threshold)).clips
    speed = np.abs(clip.qd).max(axis=1)
    assert speed[0] >= threshold and speed[-1] >= threshold
    start_s, end_s = clip.t[0] - stamps[0] / 1e9, clip.t[-1] - stamps[0] / 1e9
    assert 1.0 < start_s < 1.2 and 2.3 < end_s < 2.5
    # The frame before the first kept one is idle: the trim stops exactly at the threshold.
    before_q, before_qd = truth_at(swing, [clip.t[0] - 1 / 60])
    assert np.abs(before_qd).max() < threshold


def test_a_recording_that_never_moves_gives_no_clip_unless_trimming_is_off():
    stamps = EPOCH_NS + np.arange(500) * 2_000_000
    q = np.tile(np.linspace(-1, 1, 6), (500, 1))
    result = make_clips(stamps, stamps, q, np.zeros_like(q), ClipOptions())
    assert not result.clips and any('idle throughout' in n for n in result.notes)
    (clip,) = make_clips(stamps, stamps, q, np.zeros_like(q), ClipOptions(idle_speed_rad_s=0.0)).clips
    assert np.allclose(clip.q, q[0])


def test_a_long_silence_splits_the_recording():
    swing = Swing()
    stamps, receive, q, qd = sample(swing, 500.0, swing.total_s)
    cut = (stamps - stamps[0] > 1.0e9) & (stamps - stamps[0] < 1.3e9)  # 0.3 s lost mid-swing
    result = make_clips(stamps[~cut], receive[~cut], q[~cut], qd[~cut], ClipOptions(idle_speed_rad_s=0.0))
    assert len(result.clips) == 2
    assert result.clips[0].t[-1] < result.clips[1].t[0] - 0.25
    assert any('gap' in n for n in result.notes)


@pytest.mark.parametrize('n', [1, 2, 7, 59, 60, 61, 100])
@pytest.mark.parametrize('k', [2, 3, 5])
def test_speed_up_keeps_every_kth_frame_and_scales_velocities(n, k):
    rng = np.random.default_rng(n * 10 + k)
    clip = Clip(t=np.arange(n) / 60.0, q=rng.normal(size=(n, 6)), qd=rng.normal(size=(n, 6)))
    fast = speed_up(clip, k)
    assert len(fast) == math.ceil(n / k)
    assert np.array_equal(fast.q, clip.q[::k])
    assert np.array_equal(fast.qd, k * clip.qd[::k])
    # Played k times faster at the same rate: frames stay 1/60 s apart, from the original's first time.
    np.testing.assert_allclose(fast.t, np.arange(len(fast)) / 60.0, atol=1e-12)
    assert fast.speed_factor == k


def test_parse_speedups():
    assert parse_speedups('2,3,5') == (2, 3, 5)
    assert parse_speedups(' 4 ') == (4,)
    assert parse_speedups('none') == () and parse_speedups('') == ()
    for bad in ('1', '2,2', 'x', '0', '-3'):
        with pytest.raises(ValueError):
            parse_speedups(bad)


def make_dataset(lengths=(10, 7), speedups=(2, 3, 5)):
    originals = []
    for i, n in enumerate(lengths):
        t = 100.0 * i + np.arange(n) / 60.0
        q = np.arange(n * 6, dtype=float).reshape(n, 6) + 1000 * i
        originals.append(
            SourceClip(
                Clip(t=t, q=q, qd=-q), label=['forward', 'leftward'][i % 2], source=f'bags/clip{i}:/joint_states'
            )
        )
    return assemble_dataset(originals, speedups, JOINTS, 60.0)


def test_dataset_round_trip_has_the_issue_keys_and_plain_dtypes(tmp_path):
    dataset = make_dataset()
    path = dataset.save(tmp_path / 'sub' / 'd.npz')
    with np.load(path, allow_pickle=False) as data:
        assert NPZ_KEYS <= set(data.files)
        assert data['t'].dtype == np.float64 and data['q'].shape == (len(data['t']), 6)
        assert data['qd'].shape == data['q'].shape and data['q'].dtype == np.float64
        assert data['clip_start'].dtype.kind == 'i' and data['speed_factor'].tolist() == [1, 2, 3, 5] * 2
        assert data['clip_length'].tolist() == [10, 5, 4, 2, 7, 4, 3, 2]
        assert data['label'].tolist() == ['forward'] * 4 + ['leftward'] * 4
        assert data['source'].tolist() == ['bags/clip0:/joint_states'] * 4 + ['bags/clip1:/joint_states'] * 4
        assert float(data['rate_hz']) == 60.0 and data['rate_hz'].shape == ()
        assert data['joint_names'].tolist() == list(JOINTS)
    loaded = ReferenceDataset.load(path)
    for c in range(dataset.num_clips):
        assert np.array_equal(loaded.clip(c).q, dataset.clip(c).q)
        assert np.array_equal(loaded.clip(c).t, dataset.clip(c).t)
    # Augmented clips are exactly q[::k], k * qd[::k] of their original.
    for c in range(loaded.num_clips):
        k, original = int(loaded.speed_factor[c]), loaded.clip(int(loaded.original[c]))
        assert np.array_equal(loaded.clip(c).q, original.q[::k])
        assert np.array_equal(loaded.clip(c).qd, k * original.qd[::k])
    assert not list(tmp_path.glob('sub/*.part'))


def test_a_dataset_with_some_clips_keeps_their_frames_and_every_per_clip_array():
    dataset = make_dataset()
    keep = dataset.select(labels=['leftward'])
    subset = dataset.with_clips(keep)
    assert subset.num_clips == len(keep) == 4 and subset.label.tolist() == ['leftward'] * 4
    for i, c in enumerate(keep):
        assert np.array_equal(subset.clip(i).q, dataset.clip(c).q)
        assert subset.original[i] == dataset.original[c] and subset.source[i] == dataset.source[c]
    # Every array with one entry per clip is subset (a new per-clip field must join PER_CLIP_FIELDS).
    per_clip = {
        name
        for name, value in vars(dataset).items()
        if isinstance(value, np.ndarray) and len(value) == dataset.num_clips
    }
    assert per_clip == set(PER_CLIP_FIELDS)


@pytest.mark.parametrize('length', [1, 2, 3, 5, 8])
def test_windows_are_consecutive_states_that_never_cross_a_clip(length):
    dataset = make_dataset()
    windows = dataset.windows(length)
    expected = sum(max(0, int(n) - length + 1) for n in dataset.clip_length)
    assert windows.shape == (expected, length, 12)
    index = 0
    for c in range(dataset.num_clips):
        clip = dataset.clip(c)
        for start in range(len(clip) - length + 1):
            state = np.concatenate([clip.q[start : start + length], clip.qd[start : start + length]], axis=1)
            assert np.array_equal(windows[index], state)
            index += 1
    assert index == expected


def test_window_generator_from_a_file_matches_the_array_and_filters(tmp_path):
    dataset = make_dataset()
    path = dataset.save(tmp_path / 'd.npz')
    streamed = list(discriminator_windows(path, 2))
    assert np.array_equal(np.stack(streamed), dataset.windows(2))
    forward_originals = dataset.windows(3, labels=['forward'], speed_factors=[1])
    assert forward_originals.shape == (10 - 3 + 1, 3, 12)
    assert dataset.windows(50).shape == (0, 50, 12)
    with pytest.raises(ValueError):
        dataset.windows(0)


def _shipped_dataset(tmp_path_factory) -> ReferenceDataset | None:
    bags = pathlib.Path(__file__).resolve().parents[3] / 'bags'
    if not any(bags.glob('*/metadata.yaml')):
        return None
    from stylepong_policy.training import build_dataset

    out = tmp_path_factory.mktemp('shipped') / 'dataset.npz'
    assert build_dataset.run([str(bags), '-o', str(out)]) == 0
    return ReferenceDataset.load(out)


def test_every_shipped_clip_has_velocities_that_match_its_positions_at_the_playback_rate(tmp_path_factory):
    """Each clip of the dataset built from ros2_ws/bags, originals and speed-ups, is a motion played at
    rate_hz: its frames are 1/rate_hz apart and the derivative of its positions over its own timestamps
    agrees with its velocities. Tolerance: 25 % of the clip's RMS speed. The recorded velocities carry
    the servo's 500 Hz shake, which the 60 Hz positions average out (measured: 12-20 % on every clip,
    at every speed factor); a clip whose timestamps or velocities were off by its speed factor k would
    be off by (k - 1) / k, 50 % or more."""
    dataset = _shipped_dataset(tmp_path_factory)
    if dataset is None:
        pytest.skip('no shipped clips in ros2_ws/bags')
    for c in range(dataset.num_clips):
        clip = dataset.clip(c)
        np.testing.assert_allclose(np.diff(clip.t), 1.0 / dataset.rate_hz, rtol=1e-6)
        from_positions = np.gradient(clip.q, clip.t, axis=0)
        error = np.sqrt(np.mean((from_positions[1:-1] - clip.qd[1:-1]) ** 2))
        scale = np.sqrt(np.mean(clip.qd**2))
        assert error <= 0.25 * scale, (c, int(dataset.speed_factor[c]), error, scale)


def _speed_bumps(*bumps: tuple[int, float]) -> np.ndarray:
    """Joint velocities (frames, 2) whose speed norm is a half-sine bump of each (frames, peak rad/s), in turn."""
    speed = np.concatenate([peak * np.sin(np.linspace(0.0, np.pi, frames)) for frames, peak in bumps])
    return np.stack([speed, np.zeros_like(speed)], axis=1)


def test_a_clip_s_hit_is_the_fastest_frame_of_its_last_swing_even_when_the_back_swing_is_faster():
    # idle lead-in, a fast back-swing, a pause, a slower forward swing, a slow follow-through
    qd = _speed_bumps((5, 0.0), (21, 3.0), (4, 0.0), (21, 2.0), (11, 0.5))
    assert hit_frame(qd) == 5 + 21 + 4 + 10
    assert hit_frame(_speed_bumps((31, 2.0))) == 15  # one swing: its fastest frame
    assert hit_frame(np.zeros((6, 2))) == 0
    with pytest.raises(ValueError, match='empty'):
        hit_frame(np.zeros((0, 2)))


def test_frames_after_each_clip_s_hit_are_flagged_clip_by_clip():
    swing = _speed_bumps((11, 3.0), (4, 0.0), (11, 2.0))  # hit at frame 20 of 26
    qd = np.concatenate([swing, swing[::2]])  # an original and its x2 (hit at frame 10 of 13)
    dataset = ReferenceDataset(
        t=np.arange(len(qd)) / 60.0,
        q=np.zeros_like(qd),
        qd=qd,
        clip_start=np.array([0, 26]),
        clip_length=np.array([26, 13]),
        label=np.array(['forward'] * 2),
        speed_factor=np.array([1, 2]),
        source=np.array(['toy'] * 2),
        original=np.array([0, 0]),
        time_source=np.array(['header'] * 2),
        velocity_source=np.array(['bag'] * 2),
        rate_hz=60.0,
        joint_names=np.array(['a', 'b']),
    )
    after = dataset.after_hit()
    assert np.flatnonzero(after).tolist() == list(range(20, 26)) + list(range(36, 39))
