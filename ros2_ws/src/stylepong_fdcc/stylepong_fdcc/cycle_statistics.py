"""Timing of the control cycles: the node keeps one `CycleStatistics` and reports it at exit; the
benchmark (benchmarks/40_drag_teach.py) reads that report."""

from __future__ import annotations

import collections

import numpy as np


class CycleStatistics:
    """The last `window` control cycles: when each tick ran and how long its computation took."""

    def __init__(self, nominal_period_s: float, window: int = 60_000):
        self.nominal_period_s = nominal_period_s
        self.compute_s: collections.deque = collections.deque(maxlen=window)
        self.tick_times_s: collections.deque = collections.deque(maxlen=window)

    def record(self, tick_time_s: float, compute_s: float) -> None:
        self.tick_times_s.append(tick_time_s)
        self.compute_s.append(compute_s)

    def summary(self) -> dict:
        """Compute time mean/p99 (s), achieved rate (Hz) and missed ticks (periods without a tick)."""
        if len(self.tick_times_s) < 2:
            return {'ticks': len(self.tick_times_s)}
        ticks = np.asarray(self.tick_times_s)
        periods = np.diff(ticks)
        missed = int(np.sum(np.maximum(np.round(periods / self.nominal_period_s) - 1, 0)))
        compute = np.asarray(self.compute_s)
        return {
            'ticks': len(ticks),
            'duration_s': float(ticks[-1] - ticks[0]),
            'rate_hz': float((len(ticks) - 1) / (ticks[-1] - ticks[0])),
            'missed_ticks': missed,
            'compute_mean_s': float(compute.mean()),
            'compute_p99_s': float(np.percentile(compute, 99)),
            'period_p99_s': float(np.percentile(periods, 99)),
        }
