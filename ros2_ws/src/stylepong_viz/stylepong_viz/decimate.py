"""Display decimation and bounded histories, by message time (no ROS, no rerun here).

The viewer receives joint states at 500 Hz; a browser draws at most ~60 frames a second and a plot line
gains nothing from more than a few hundred points a second. These keep what is drawn small, decided by
the messages' own stamps, so that a live graph and a bag replayed as fast as it can be read are
decimated alike.
"""

from __future__ import annotations

import collections

import numpy as np


class Decimator:
    """Lets a sample through when at least period_s of message time passed since the last one it let through.

    A stamp that goes backwards by more than a period (a restarted simulation, a new clip) restarts it.
    """

    def __init__(self, rate_hz: float):
        if not rate_hz > 0.0:
            raise ValueError(f'decimation rate must be > 0 Hz, got {rate_hz}')
        self.period_s = 1.0 / rate_hz
        self._last_s: float | None = None

    def due(self, time_s: float) -> bool:
        """True (and the sample is taken) when time_s is a period or more after the last taken one."""
        last = self._last_s
        if last is None or time_s - last >= self.period_s or time_s < last - self.period_s:
            # Stay on the rate's grid (no drift from late samples) unless far behind or restarted.
            self._last_s = (
                time_s if last is None or not 0.0 <= time_s - last < 2.0 * self.period_s else last + self.period_s
            )
            return True
        return False


class Trail:
    """The last `seconds` of 3D points by message time (a ball's trail, the paddle's path)."""

    def __init__(self, seconds: float, max_points: int = 2000):
        self.seconds = seconds
        self._points: collections.deque = collections.deque(maxlen=max_points)

    def add(self, time_s: float, point_m) -> None:
        if self._points and time_s < self._points[-1][0]:
            self._points.clear()  # time went back: a new run or clip, not a jump across the cell
        self._points.append((time_s, tuple(float(v) for v in point_m)))
        while self._points and self._points[0][0] < time_s - self.seconds:
            self._points.popleft()

    def clear(self) -> None:
        self._points.clear()

    def points(self) -> np.ndarray:
        """(n, 3) array, oldest first."""
        return np.array([p for _, p in self._points], dtype=float).reshape(-1, 3)


class ColumnBuffer:
    """Rows of (time, values) gathered between two flushes, handed out as arrays for one batched send."""

    def __init__(self, width: int):
        self.width = width
        self._times: list[float] = []
        self._rows: list[list[float]] = []

    def add(self, time_s: float, values) -> None:
        row = [float(v) for v in values]
        if len(row) != self.width:
            raise ValueError(f'expected {self.width} values, got {len(row)}')
        self._times.append(time_s)
        self._rows.append(row)

    def __len__(self) -> int:
        return len(self._times)

    def take(self) -> tuple[np.ndarray, np.ndarray]:
        """(times (n,), values (n, width)) and the buffer emptied."""
        times = np.array(self._times, dtype=float)
        values = np.array(self._rows, dtype=float).reshape(-1, self.width)
        self._times, self._rows = [], []
        return times, values
