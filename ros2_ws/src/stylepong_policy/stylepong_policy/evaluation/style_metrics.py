"""How a stroke moves: its DTW distance to the demonstrations, and its speed, acceleration and jerk.

DTW (the paper's Table II: "Dynamic Time Warping" on joint-position sequences, after Mueller,
"Information Retrieval for Music and Motion"). The convention, stated because DTW figures are only
comparable under one:
  local cost   the Euclidean distance between two frames' joint positions (rad, all six joints);
  steps        symmetric and unweighted: (i-1, j-1), (i-1, j), (i, j-1), each adding the local cost
               of (i, j) once: D(i, j) = c(i, j) + min(D(i-1, j-1), D(i-1, j), D(i, j-1));
  result       D(n-1, m-1), the path's summed cost, not normalised; also divided by the number of
               frame pairs on the optimal path (its length) to compare strokes of different lengths;
  no window, no step limit.
It is computed by dtaidistance (C implementation):
  dtaidistance.dtw_ndim.distance_fast(a, b, inner_dist='euclidean')                  the distance
  dtaidistance.dtw_ndim.warping_paths_fast(a, b, inner_dist='euclidean') with
  dtaidistance.dtw.best_path(paths)                                                  the path
The same distances as dtw-python's dtw(a, b, dist_method='euclidean', step_pattern='symmetric1'). dtaidistance's
default inner distance is the squared one with a square root taken at the end, which is another
measure, so inner_dist is always given. (Its dtw.warping_path_fast does not use inner_dist for the
path it returns, so it is not used here.)

A stroke is compared with every reference clip of its direction (all speed factors: the discriminator
learns from all of them) and its distance is the smallest; a direction's figure is the mean over its
strokes.

Where the distance lies (beyond the paper; `cost_breakdown`). Each frame pair (i, j) on the optimal
path adds c = |d|, d = stroke[i] - clip[j]; joint k's part of it is c d_k^2 / |d|^2, so the parts add
up to the distance exactly. The pair's phase is that of the stroke's frame i: `waiting` until
SWING_S before the paddle's hit, `swing` from there to the hit, `follow_through` after it (a stroke
without a hit has no follow-through; its last SWING_S counts as its swing).

Smoothness (beyond the paper): from the 60 Hz joint positions by backward finite differences,
  qdot[k] = (q[k] - q[k-1]) / dt, qddot = the same of qdot, jerk = the same of qddot;
  peak joint speed         max over frames and joints of |qdot|    (rad/s)
  peak joint acceleration  max over frames and joints of |qddot|   (rad/s^2)
  mean absolute jerk       mean over frames and joints of |jerk|   (rad/s^3)
Differences of positions rather than the simulator's velocities, so a recorded trajectory from
anywhere (a real arm's joint states resampled to 60 Hz) gives comparable figures.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass

import numpy as np
from dtaidistance import dtw as dtai_dtw
from dtaidistance import dtw_ndim

INNER_DISTANCE = 'euclidean'


PHASES = ('waiting', 'swing', 'follow_through')
SWING_S = 0.25  # the forward swing before the hit: about the policies' (0.2-0.3 s at 60 Hz)


@dataclass(frozen=True)
class DtwMatch:
    """A stroke's nearest reference clip."""

    distance: float  # summed Euclidean cost along the optimal path (rad)
    path_length: int  # frame pairs on that path
    clip: int  # index of the clip in the reference dataset
    path: tuple[tuple[int, int], ...] = ()  # the optimal path's (stroke frame, clip frame) pairs

    @property
    def distance_per_step(self) -> float:
        return self.distance / self.path_length


def _series(q_rad: np.ndarray) -> np.ndarray:
    """The (frames, joints) float64 C-ordered array the C implementation reads."""
    q = np.ascontiguousarray(q_rad, dtype=np.float64)
    if q.ndim != 2 or len(q) == 0:
        raise ValueError(f'a joint-position sequence must be (frames > 0, joints), got shape {q.shape}')
    return q


def dtw_distance_rad(a_rad: np.ndarray, b_rad: np.ndarray) -> float:
    """DTW distance between two joint-position sequences (the convention of the module docstring)."""
    a, b = _series(a_rad), _series(b_rad)
    if a.shape[1] != b.shape[1]:
        raise ValueError(f'sequences have {a.shape[1]} and {b.shape[1]} joints')
    return float(dtw_ndim.distance_fast(a, b, inner_dist=INNER_DISTANCE))


def dtw_path(a_rad: np.ndarray, b_rad: np.ndarray) -> tuple[float, list[tuple[int, int]]]:
    """DTW distance and one optimal warping path [(i, j), ...] from (0, 0) to (n-1, m-1)."""
    a, b = _series(a_rad), _series(b_rad)
    distance, paths = dtw_ndim.warping_paths_fast(a, b, inner_dist=INNER_DISTANCE)
    return float(distance), [(int(i), int(j)) for i, j in dtai_dtw.best_path(paths)]


def nearest_reference(stroke_rad: np.ndarray, references: Sequence[tuple[int, np.ndarray]]) -> DtwMatch:
    """The reference clip (index, joint positions) nearest to the stroke by DTW, with its path length."""
    if not references:
        raise ValueError('no reference clip to compare with')
    distances = [dtw_distance_rad(stroke_rad, clip) for _, clip in references]
    best = int(np.argmin(distances))
    index, clip = references[best]
    _, path = dtw_path(stroke_rad, clip)
    return DtwMatch(distance=distances[best], path_length=len(path), clip=int(index), path=tuple(path))


@dataclass(frozen=True)
class CostBreakdown:
    """A DTW distance split by joint and by phase of the stroke (both sum to the distance, rad)."""

    by_joint_rad: np.ndarray  # [joints]
    by_phase_rad: dict[str, float]  # PHASES


def stroke_phases(frames: int, hit_frame: int, rate_hz: float) -> np.ndarray:
    """Index into PHASES of each of a stroke's frames (hit_frame < 0: no hit)."""
    hit = hit_frame if hit_frame >= 0 else frames
    swing_start = hit - int(round(SWING_S * rate_hz))
    index = np.arange(frames)
    return np.where(index < swing_start, 0, np.where(index < hit, 1, 2))


def cost_breakdown(
    stroke_rad: np.ndarray, clip_rad: np.ndarray, path: Sequence[tuple[int, int]], hit_frame: int, rate_hz: float
) -> CostBreakdown:
    """Split the cost of a warping path (module docstring, "Where the distance lies")."""
    pairs = np.asarray(path, dtype=np.int64)
    difference = _series(stroke_rad)[pairs[:, 0]] - _series(clip_rad)[pairs[:, 1]]
    squared = difference**2
    cost = np.sqrt(squared.sum(axis=1))
    # c d_k^2 / |d|^2 = d_k^2 / c; a pair of identical frames adds nothing to any joint.
    by_joint = (squared / np.where(cost > 0.0, cost, 1.0)[:, None]).sum(axis=0)
    phase = stroke_phases(len(stroke_rad), hit_frame, rate_hz)[pairs[:, 0]]
    by_phase = {name: float(cost[phase == k].sum()) for k, name in enumerate(PHASES)}
    return CostBreakdown(by_joint_rad=by_joint, by_phase_rad=by_phase)


def reference_clips(dataset, label: str, speed_factors: Sequence[int] | None = None) -> list[tuple[int, np.ndarray]]:
    """(index, joint positions) of every clip of a stylepong_policy.training.dataset.ReferenceDataset with this label
    and one of these speed factors (None: any)."""
    return [(int(c), dataset.clip(int(c)).q) for c in dataset.select(labels=[label], speed_factors=speed_factors)]


@dataclass(frozen=True)
class Smoothness:
    """Peak joint speed and acceleration and mean absolute jerk of a set of strokes."""

    peak_joint_speed_rad_s: float
    peak_joint_acceleration_rad_s2: float
    mean_abs_jerk_rad_s3: float


def smoothness(q_rad: np.ndarray, rate_hz: float) -> Smoothness:
    """Peak speed, peak acceleration and mean absolute jerk of a joint trajectory (module docstring)."""
    q = np.asarray(q_rad, dtype=np.float64)
    if q.ndim != 2 or len(q) < 4:
        raise ValueError(f'need at least 4 frames of (frames, joints) positions for a jerk, got shape {q.shape}')
    dt_s = 1.0 / rate_hz
    velocity = np.diff(q, axis=0) / dt_s
    acceleration = np.diff(velocity, axis=0) / dt_s
    jerk = np.diff(acceleration, axis=0) / dt_s
    return Smoothness(
        peak_joint_speed_rad_s=float(np.abs(velocity).max()),
        peak_joint_acceleration_rad_s2=float(np.abs(acceleration).max()),
        mean_abs_jerk_rad_s3=float(np.abs(jerk).mean()),
    )


def mean_smoothness(values: Iterable[Smoothness]) -> dict[str, float] | None:
    """Each measure averaged over strokes (None for no stroke)."""
    values = list(values)
    if not values:
        return None
    return {name: float(np.mean([getattr(v, name) for v in values])) for name in Smoothness.__dataclass_fields__}


def reference_smoothness(dataset, labels: Sequence[str], speed_factor: int) -> dict[str, dict[str, float] | None]:
    """The demonstrations' own smoothness per label (its clips of one speed factor), for scale; clips too
    short for a jerk (under 4 frames) are left out."""
    table = {}
    for label in labels:
        clips = dataset.select(labels=[label], speed_factors=[speed_factor])
        values = [smoothness(dataset.clip(int(c)).q, dataset.rate_hz) for c in clips if dataset.clip_length[c] >= 4]
        table[label] = mean_smoothness(values)
    return table
