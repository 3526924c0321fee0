"""Reference motions for the AMP discriminator: recordings -> 60 Hz clips -> augmentation -> .npz (no rclpy).

A clip is a run of consecutive frames on a fixed grid of `rate_hz` (60 Hz, the policy's rate), each frame
a joint position q (rad) and velocity qd (rad/s) in URDF joint order. The paper's augmentation makes a
clip k times faster by keeping every k-th frame and multiplying the velocities by k; the originals
stay in the dataset. The discriminator sees windows of L consecutive frames that never cross a clip
boundary (`ReferenceDataset.windows`, `discriminator_windows`).

The .npz layout (C clips, N frames in all; clip c is frames clip_start[c] .. clip_start[c]+clip_length[c]-1):
  t            (N,)   float64  seconds on the recording's clock (header stamp time since the epoch);
                               a sped-up clip starts at its original's first time and runs k times
                               faster, so every clip's frames are 1/rate_hz apart
  q, qd        (N, J) float64  rad, rad/s, columns in joint_names order
  clip_start, clip_length, speed_factor (C,) int64; speed_factor 1 for an original
  label, source (C,) str       source = "<bag directory>:<topic>", shared by an original and its sped-up clips
  original     (C,) int64      index of the clip an augmented clip was made from (itself for originals)
  time_source, velocity_source (C,) str   'header' | 'receive'; 'bag' | 'positions'
  rate_hz      ()     float64  frame rate every clip is meant to be played at
  joint_names  (J,)   str
"""

from __future__ import annotations

import math
import os
import pathlib
import tempfile
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field, replace

import numpy as np

from stylepong_common.settings import at_least, check_ranges, non_negative, positive
from stylepong_sim.world_spec import POLICY_RATE_HZ

DEFAULT_RATE_HZ = POLICY_RATE_HZ  # clips are played at the rate the policy acts
DEFAULT_SPEEDUPS = (2, 3, 5)
NS_PER_S = 1_000_000_000


@dataclass(frozen=True)
class ClipOptions:
    """How a recording becomes clips."""

    rate_hz: float = positive(DEFAULT_RATE_HZ)
    # Frames at the start and end whose fastest joint moves slower than this are idle (0: keep all).
    idle_speed_rad_s: float = non_negative(0.05)
    # A longer silence (or 5 median message periods, whichever is longer) splits a recording.
    max_gap_s: float = positive(0.1)
    # The bag's velocities are used when they match the position derivative per joint within
    # abs + rel * rms(derivative) (rms over the clip); else velocities come from the positions.
    velocity_abs_tolerance_rad_s: float = non_negative(0.05)
    velocity_rel_tolerance: float = non_negative(0.2)
    min_frames: int = at_least(2, 2)

    def validate(self) -> None:
        check_ranges(self)


@dataclass
class Clip:
    """Frames on a fixed grid: t (s, recording clock), q (rad), qd (rad/s)."""

    t: np.ndarray
    q: np.ndarray
    qd: np.ndarray
    time_source: str = 'header'
    velocity_source: str = 'positions'
    speed_factor: int = 1

    def __len__(self) -> int:
        return len(self.t)


@dataclass
class ClipResult:
    """The clips cut from one recording and notes on how."""

    clips: list[Clip] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)


# ---------------------------------------------------------------------------------------------
# Recording -> clips


def choose_times_ns(header_stamp_ns: np.ndarray, receive_time_ns: np.ndarray) -> tuple[np.ndarray, str, str | None]:
    """Header stamps when all are set and increasing, else receive times; (times, source, warning)."""
    zero = int((header_stamp_ns <= 0).sum())
    not_increasing = int((np.diff(header_stamp_ns) <= 0).sum())
    if zero == 0 and not_increasing == 0:
        return header_stamp_ns, 'header', None
    reasons = []
    if zero:
        reasons.append(f'{zero} zero')
    if not_increasing:
        reasons.append(f'{not_increasing} not increasing')
    return receive_time_ns, 'receive', f'header stamps unusable ({", ".join(reasons)}): timed by receive time'


def drop_repeated(times_ns: np.ndarray) -> np.ndarray:
    """Indices of samples that move time forward (receive times can repeat); keeps the first of a run."""
    keep = np.ones(len(times_ns), dtype=bool)
    keep[1:] = np.diff(np.maximum.accumulate(times_ns)) > 0
    return np.flatnonzero(keep)


def split_at_gaps(times_ns: np.ndarray, max_gap_s: float) -> list[slice]:
    """Runs of samples without a silence longer than max(max_gap_s, 5 median periods)."""
    steps = np.diff(times_ns)
    if not len(steps):
        return [slice(0, len(times_ns))]
    threshold_ns = max(max_gap_s * NS_PER_S, 5.0 * float(np.median(steps)))
    cuts = np.flatnonzero(steps > threshold_ns) + 1
    bounds = [0, *cuts.tolist(), len(times_ns)]
    return [slice(a, b) for a, b in zip(bounds[:-1], bounds[1:])]


def grid_times_s(span_s: float, rate_hz: float) -> np.ndarray:
    """0, 1/rate, ... up to span_s (inclusive within float rounding)."""
    count = int(math.floor(span_s * rate_hz + 1e-9)) + 1
    return np.arange(count) / rate_hz


def interpolate_columns(x_new: np.ndarray, x: np.ndarray, values: np.ndarray) -> np.ndarray:
    """Linear interpolation of each column of `values` (sampled at `x`) at `x_new`."""
    return np.stack([np.interp(x_new, x, values[:, j]) for j in range(values.shape[1])], axis=1)


def velocity_from_positions(q: np.ndarray, rate_hz: float) -> np.ndarray:
    """Central differences on the grid (second-order one-sided at the ends)."""
    if len(q) < 3:
        return np.gradient(q, 1.0 / rate_hz, axis=0) if len(q) > 1 else np.zeros_like(q)
    return np.gradient(q, 1.0 / rate_hz, axis=0, edge_order=2)


def velocity_mismatch_rad_s(qd_bag: np.ndarray, qd_positions: np.ndarray) -> np.ndarray:
    """Per-joint rms difference between the bag's velocities and the position derivative."""
    return np.sqrt(np.mean((qd_bag - qd_positions) ** 2, axis=0))


def bag_velocity_is_consistent(
    qd_bag: np.ndarray, qd_positions: np.ndarray, options: ClipOptions
) -> tuple[bool, float]:
    """Whether the bag's velocities match the position derivative within the tolerances, and the worst mismatch."""
    mismatch = velocity_mismatch_rad_s(qd_bag, qd_positions)
    scale = np.sqrt(np.mean(qd_positions**2, axis=0))
    allowed = options.velocity_abs_tolerance_rad_s + options.velocity_rel_tolerance * scale
    return bool(np.all(mismatch <= allowed)), float(mismatch.max())


def idle_trim(qd: np.ndarray, idle_speed_rad_s: float) -> slice | None:
    """Frames from the first to the last whose fastest joint reaches the threshold; None if none does."""
    if idle_speed_rad_s <= 0:
        return slice(0, len(qd))
    moving = np.abs(qd).max(axis=1) >= idle_speed_rad_s
    if not moving.any():
        return None
    first = int(np.argmax(moving))
    last = len(moving) - 1 - int(np.argmax(moving[::-1]))
    return slice(first, last + 1)


# A demonstration's stroke: the arm leaves home, swings back, nearly stops, then swings through the
# hit into its follow-through. Joint-speed norms (rad/s) relative to the clip's fastest frame mark these:
# the motion has begun once the speed passes SWING_MOVING_SHARE of the top, and the pause before the
# forward swing is the first frame after that slower than SWING_PAUSE_SHARE of it.
SWING_MOVING_SHARE = 0.3
SWING_PAUSE_SHARE = 0.15


def hit_frame(qd_rad_s: np.ndarray) -> int:
    """The frame of a clip where a ball would be met: the fastest frame of its last swing.

    A ball-less demonstration marks no hit. The forward swing is the one after the pause that ends the
    back-swing, so the hit is the fastest frame from that pause on (the back-swing may be the faster of
    the two); a clip that does not swing again after slowing down is one swing, and its fastest frame is
    the hit."""
    speed = np.linalg.norm(np.asarray(qd_rad_s, dtype=float), axis=1)
    if not len(speed):
        raise ValueError('an empty clip has no hit')
    top = float(speed.max())
    moving = np.flatnonzero(speed > SWING_MOVING_SHARE * top)
    if not len(moving):
        return int(np.argmax(speed))
    paused = np.flatnonzero(speed[moving[0] :] < SWING_PAUSE_SHARE * top)
    pause = int(moving[0] + paused[0]) if len(paused) else len(speed)
    if not (speed[pause:] > SWING_MOVING_SHARE * top).any():  # the slow end of a single swing
        return int(np.argmax(speed))
    return pause + int(np.argmax(speed[pause:]))


def make_clips(
    header_stamp_ns: np.ndarray,
    receive_time_ns: np.ndarray,
    position_rad: np.ndarray,
    velocity_rad_s: np.ndarray,
    options: ClipOptions = ClipOptions(),
) -> ClipResult:
    """Clips from one recording's samples (rows in recording order; velocity NaN where absent)."""
    options.validate()
    result = ClipResult()
    header_stamp_ns = np.asarray(header_stamp_ns, dtype=np.int64)
    receive_time_ns = np.asarray(receive_time_ns, dtype=np.int64)
    position = np.asarray(position_rad, dtype=float)
    velocity = np.asarray(velocity_rad_s, dtype=float)
    # A message published or recorded twice is not a clock problem: drop exact repeats first.
    repeats = np.zeros(len(header_stamp_ns), dtype=bool)
    repeats[1:] = (
        (np.diff(header_stamp_ns) == 0) & (header_stamp_ns[1:] > 0) & np.all(position[1:] == position[:-1], axis=1)
    )
    if repeats.any():
        result.notes.append(f'{int(repeats.sum())} repeated messages (same stamp and positions) dropped')
        unique = ~repeats
        header_stamp_ns, receive_time_ns = header_stamp_ns[unique], receive_time_ns[unique]
        position, velocity = position[unique], velocity[unique]
    times_ns, time_source, warning = choose_times_ns(header_stamp_ns, receive_time_ns)
    if warning:
        result.notes.append(warning)
    keep = drop_repeated(times_ns)
    if len(keep) < len(times_ns):
        result.notes.append(f'{len(times_ns) - len(keep)} samples with a repeated or earlier time dropped')
    times_ns = times_ns[keep]
    # Unwrap on the raw samples, before resampling: a joint recorded wrapped into [-pi, pi) jumps by
    # 2 pi between two samples, and only there can the jump be told from motion.
    position = np.unwrap(position[keep], axis=0)
    velocity = velocity[keep]
    segments = split_at_gaps(times_ns, options.max_gap_s)
    if len(segments) > 1:
        result.notes.append(f'split at {len(segments) - 1} gap(s) in the recording into {len(segments)} parts')
    for number, segment in enumerate(segments, start=1):
        where = f'part {number}: ' if len(segments) > 1 else ''
        seg_times = times_ns[segment]
        if len(seg_times) < 2:
            result.notes.append(f'{where}a single sample')
            continue
        t_rel_s = (seg_times - seg_times[0]) / NS_PER_S
        grid_s = grid_times_s(float(t_rel_s[-1]), options.rate_hz)
        q = interpolate_columns(grid_s, t_rel_s, position[segment])
        qd_positions = velocity_from_positions(q, options.rate_hz)
        qd, velocity_source = qd_positions, 'positions'
        seg_velocity = velocity[segment]
        if np.isfinite(seg_velocity).all():
            qd_bag = interpolate_columns(grid_s, t_rel_s, seg_velocity)
            consistent, mismatch = bag_velocity_is_consistent(qd_bag, qd_positions, options)
            if consistent:
                qd, velocity_source = qd_bag, 'bag'
            else:
                result.notes.append(
                    f'{where}velocities in the bag disagree with the positions (worst joint '
                    f'rms {mismatch:.3g} rad/s): derived from the positions'
                )
        elif np.isnan(seg_velocity).all():
            result.notes.append(f'{where}no velocities in the bag: derived from the positions')
        else:
            missing = int(np.isnan(seg_velocity).any(axis=1).sum())
            result.notes.append(
                f'{where}{missing} of {len(seg_velocity)} messages lack velocities: all derived from the positions'
            )
        frames = idle_trim(qd, options.idle_speed_rad_s)
        if frames is None:
            peak = float(np.abs(qd).max()) if qd.size else 0.0
            result.notes.append(
                f'{where}idle throughout (fastest joint {peak:.3g} rad/s < '
                f'{options.idle_speed_rad_s:g} rad/s; --idle-speed-rad-s 0 keeps it)'
            )
            continue
        trimmed_s = (frames.start / options.rate_hz, (len(q) - frames.stop) / options.rate_hz)
        if frames.start or frames.stop < len(q):
            result.notes.append(f'{where}trimmed idle lead-in {trimmed_s[0]:.2f} s, lead-out {trimmed_s[1]:.2f} s')
        q, qd, grid_s = q[frames], qd[frames], grid_s[frames]
        if len(q) < options.min_frames:
            result.notes.append(f'{where}only {len(q)} frame(s) of motion')
            continue
        t_s = seg_times[0] / NS_PER_S + grid_s
        result.clips.append(Clip(t=t_s, q=q, qd=qd, time_source=time_source, velocity_source=velocity_source))
    return result


# ---------------------------------------------------------------------------------------------
# Augmentation


def speed_up(clip: Clip, k: int) -> Clip:
    """The paper's augmentation: every k-th frame, velocities times k (ceil(n/k) frames).

    The sped-up clip is the motion played k times faster at the same frame rate, so its frames keep the
    original's spacing (1/rate_hz): its time runs k times faster from the clip's first frame, and the
    finite differences of its positions match its (scaled) velocities.
    """
    if k < 1:
        raise ValueError(f'speed-up factor must be >= 1, got {k}')
    t = clip.t[0] + (clip.t[::k] - clip.t[0]) / k
    return Clip(
        t=t,
        q=clip.q[::k].copy(),
        qd=k * clip.qd[::k],
        time_source=clip.time_source,
        velocity_source=clip.velocity_source,
        speed_factor=clip.speed_factor * k,
    )


def parse_speedups(text: str) -> tuple[int, ...]:
    """'2,3,5' -> (2, 3, 5); '' or 'none' -> (). Each factor an integer >= 2, no repeats."""
    text = text.strip()
    if text.lower() in ('', 'none'):
        return ()
    factors = []
    for part in text.split(','):
        part = part.strip()
        try:
            k = int(part)
        except ValueError:
            raise ValueError(f'speed-up factor {part!r} is not an integer') from None
        if k < 2:
            raise ValueError(f'speed-up factor {k} must be >= 2 (the original is always kept)')
        if k in factors:
            raise ValueError(f'speed-up factor {k} given twice')
        factors.append(k)
    return tuple(factors)


# ---------------------------------------------------------------------------------------------
# The dataset


def window_start_indices(
    clip_start: Sequence[int] | np.ndarray, clip_length: Sequence[int] | np.ndarray, length: int
) -> np.ndarray:
    """First frame index of every window of `length` consecutive frames lying inside one clip, for clips
    that start at clip_start and hold clip_length frames (a shorter clip has none)."""
    if length < 1:
        raise ValueError(f'window length must be >= 1, got {length}')
    starts = [
        np.arange(start, start + count - length + 1) for start, count in zip(clip_start, clip_length) if count >= length
    ]
    return np.concatenate(starts).astype(np.int64) if starts else np.zeros(0, dtype=np.int64)


@dataclass
class SourceClip:
    """An original clip with where it came from."""

    clip: Clip
    label: str
    source: str


# ReferenceDataset's arrays with one entry per clip (the others are per frame or whole-dataset).
PER_CLIP_FIELDS = (
    'clip_start',
    'clip_length',
    'label',
    'speed_factor',
    'source',
    'original',
    'time_source',
    'velocity_source',
)


@dataclass
class ReferenceDataset:
    """All clips, concatenated (see the module docstring for the layout)."""

    t: np.ndarray
    q: np.ndarray
    qd: np.ndarray
    clip_start: np.ndarray
    clip_length: np.ndarray
    label: np.ndarray
    speed_factor: np.ndarray
    source: np.ndarray
    original: np.ndarray
    time_source: np.ndarray
    velocity_source: np.ndarray
    rate_hz: float
    joint_names: tuple[str, ...]

    @property
    def num_clips(self) -> int:
        return len(self.clip_start)

    def clip(self, index: int) -> Clip:
        frames = slice(int(self.clip_start[index]), int(self.clip_start[index] + self.clip_length[index]))
        return Clip(
            t=self.t[frames],
            q=self.q[frames],
            qd=self.qd[frames],
            time_source=str(self.time_source[index]),
            velocity_source=str(self.velocity_source[index]),
            speed_factor=int(self.speed_factor[index]),
        )

    def states(self) -> np.ndarray:
        """(N, 2J) arm states [q, qd] per frame, the discriminator's per-frame input."""
        return np.concatenate([self.q, self.qd], axis=1)

    def after_hit(self) -> np.ndarray:
        """(N,) bool per frame: the frame lies at or after its clip's hit (`hit_frame`)."""
        after = np.zeros(len(self.q), dtype=bool)
        for start, length in zip(self.clip_start, self.clip_length):
            start, length = int(start), int(length)
            after[start + hit_frame(self.qd[start : start + length]) : start + length] = True
        return after

    def select(self, labels: Sequence[str] | None = None, speed_factors: Sequence[int] | None = None) -> np.ndarray:
        """Indices of the clips with one of these labels and speed factors (None: any)."""
        chosen = np.ones(self.num_clips, dtype=bool)
        if labels is not None:
            chosen &= np.isin(self.label, list(labels))
        if speed_factors is not None:
            chosen &= np.isin(self.speed_factor, list(speed_factors))
        return np.flatnonzero(chosen)

    def with_clips(self, clips: np.ndarray) -> ReferenceDataset:
        """The same frames with only these clips listed (a subset that keeps every frame index valid)."""
        return replace(self, **{name: getattr(self, name)[clips] for name in PER_CLIP_FIELDS})

    def window_starts(self, length: int, clips: np.ndarray | None = None) -> np.ndarray:
        """First frame index of every window of `length` frames lying inside one of these clips (all)."""
        clips = np.arange(self.num_clips) if clips is None else np.asarray(clips)
        return window_start_indices(self.clip_start[clips], self.clip_length[clips], length)

    def windows(
        self, length: int, *, labels: Sequence[str] | None = None, speed_factors: Sequence[int] | None = None
    ) -> np.ndarray:
        """All windows of `length` consecutive states: (W, length, 2J) float64, states [q, qd]."""
        starts = self.window_starts(length, self.select(labels, speed_factors))
        states = self.states()
        if not len(starts):
            return np.zeros((0, length, states.shape[1]))
        return states[starts[:, None] + np.arange(length)[None, :]]

    def save(self, path: str | os.PathLike) -> pathlib.Path:
        """Write the .npz atomically (a half-written dataset never replaces a good one)."""
        path = pathlib.Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        arrays = {
            't': self.t.astype(np.float64),
            'q': self.q.astype(np.float64),
            'qd': self.qd.astype(np.float64),
            'clip_start': self.clip_start.astype(np.int64),
            'clip_length': self.clip_length.astype(np.int64),
            'label': np.asarray(self.label, dtype=str),
            'speed_factor': self.speed_factor.astype(np.int64),
            'source': np.asarray(self.source, dtype=str),
            'original': self.original.astype(np.int64),
            'time_source': np.asarray(self.time_source, dtype=str),
            'velocity_source': np.asarray(self.velocity_source, dtype=str),
            'rate_hz': np.float64(self.rate_hz),
            'joint_names': np.asarray(self.joint_names, dtype=str),
        }
        handle, temporary = tempfile.mkstemp(prefix=path.name + '.', suffix='.part', dir=path.parent)
        try:
            with os.fdopen(handle, 'wb') as stream:
                np.savez(stream, **arrays)
            os.chmod(temporary, 0o644)  # mkstemp makes it private; a dataset is meant to be shared
            os.replace(temporary, path)
        except BaseException:
            pathlib.Path(temporary).unlink(missing_ok=True)
            raise
        return path

    @classmethod
    def load(cls, path: str | os.PathLike) -> 'ReferenceDataset':
        with np.load(path, allow_pickle=False) as data:
            count = len(data['clip_start'])

            def optional(key: str, default) -> np.ndarray:
                return data[key] if key in data.files else np.asarray([default] * count)

            arrays = {
                key: data[key]
                for key in ('t', 'q', 'qd', 'clip_start', 'clip_length', 'label', 'speed_factor', 'source')
            }
            # Written by older versions without these: unknown for every clip.
            for key, default in (('original', -1), ('time_source', ''), ('velocity_source', '')):
                arrays[key] = optional(key, default)
            return cls(**arrays, rate_hz=float(data['rate_hz']), joint_names=tuple(str(n) for n in data['joint_names']))


def assemble_dataset(
    originals: Sequence[SourceClip], speedups: Sequence[int], joint_names: Sequence[str], rate_hz: float
) -> ReferenceDataset:
    """Each original followed by its sped-up versions, concatenated."""
    clips, labels, sources, originals_index = [], [], [], []
    for item in originals:
        first = len(clips)
        for clip in [item.clip] + [speed_up(item.clip, k) for k in speedups]:
            clips.append(clip)
            labels.append(item.label)
            sources.append(item.source)
            originals_index.append(first)
    n_joints = len(joint_names)
    lengths = np.array([len(c) for c in clips], dtype=np.int64)
    starts = np.concatenate([[0], np.cumsum(lengths)[:-1]]).astype(np.int64) if len(clips) else np.zeros(0, np.int64)

    def stack(attribute: str, width: int | None) -> np.ndarray:
        parts = [getattr(c, attribute) for c in clips]
        if parts:
            return np.concatenate(parts)
        return np.zeros((0, width)) if width else np.zeros(0)

    return ReferenceDataset(
        t=stack('t', None),
        q=stack('q', n_joints),
        qd=stack('qd', n_joints),
        clip_start=starts,
        clip_length=lengths,
        label=np.asarray(labels, dtype=str),
        speed_factor=np.array([c.speed_factor for c in clips], dtype=np.int64),
        source=np.asarray(sources, dtype=str),
        original=np.array(originals_index, dtype=np.int64),
        time_source=np.asarray([c.time_source for c in clips], dtype=str),
        velocity_source=np.asarray([c.velocity_source for c in clips], dtype=str),
        rate_hz=float(rate_hz),
        joint_names=tuple(joint_names),
    )


def discriminator_windows(
    dataset: ReferenceDataset | str | os.PathLike,
    length: int,
    *,
    labels: Sequence[str] | None = None,
    speed_factors: Sequence[int] | None = None,
) -> Iterator[np.ndarray]:
    """Yield every window of `length` consecutive arm states [q, qd] ((length, 2J) arrays), clip by clip."""
    if not isinstance(dataset, ReferenceDataset):
        dataset = ReferenceDataset.load(dataset)
    states = dataset.states()
    for start in dataset.window_starts(length, dataset.select(labels, speed_factors)):
        yield states[start : start + length]
