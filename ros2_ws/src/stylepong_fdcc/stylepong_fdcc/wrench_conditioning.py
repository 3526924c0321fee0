"""From the wrist sensor's reading to the hand's wrench (docs/DESIGN.md, "FDCC safety layer").

One stated convention: the sensor gives the wrench the environment applies on the tool, in tool0 axes,
about tool0's origin; `WrenchConditioner.output` gives the hand's wrench in base_link axes about the
same point, which is what the solver takes.
- Rejection: a wrench with a non-finite entry, or beyond `reject_force_n` / `reject_torque_nm` (well
  beyond any sensor's range), is a sensor fault, never an input.
- Tool gravity compensation: the sensor reading includes the paddle's weight; the paddle's mass and
  centre of mass come from the robot model (`stylepong_description`) and its weight is removed at the
  current tool orientation, so reorienting the tool causes no drift.
- Taring: the sensor bias is the mean gravity-compensated reading over the last `tare_window_s`.
- Low-pass (first order, cutoff in Hz, discretised with the real sample interval), a deadband (the
  magnitude is reduced by the deadband, so the response stays continuous), a magnitude clamp.
"""

from __future__ import annotations

import collections
import math

import numpy as np
import pinocchio as pin

from stylepong_description import robot_model
from stylepong_description.robot_model import ToolLoad
from stylepong_fdcc.fdcc_config import FdccConfig


def tool_load_from_model(model: pin.Model) -> ToolLoad:
    """The paddle's mass and centre of mass in tool0, as the robot model describes them.

    Pinocchio folds fixed links into their parent joint's body but keeps each fixed link's inertia on
    the frame of the fixed joint that attaches it; that is where the paddle's numbers are read.
    """
    paddle = model.frames[model.getFrameId(robot_model.PADDLE_BODY)]
    attach = model.frames[paddle.parentFrame]
    tool = model.frames[model.getFrameId(robot_model.TOOL_FRAME)]
    # Both frames hang on the same joint: tool0 <- joint -> attachment frame.
    tool_m_attach = tool.placement.actInv(attach.placement)
    return ToolLoad(mass_kg=float(attach.inertia.mass), com_m=np.array(tool_m_attach.act(attach.inertia.lever)))


def cross3(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """a x b for 3-vectors (np.cross costs ten times as much at this size, every control cycle)."""
    return np.array([a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]])


def gravity_wrench_on_tool(load: ToolLoad, tool_rotation_base: np.ndarray, gravity_base_m_s2: np.ndarray) -> np.ndarray:
    """Wrench (force N, torque N m; tool0 axes, about tool0's origin) that gravity applies on the tool."""
    force_tool = tool_rotation_base.T @ (load.mass_kg * gravity_base_m_s2)
    return np.concatenate([force_tool, cross3(load.com_m, force_tool)])


def wrench_fault(wrench: np.ndarray, reject_force_n: float, reject_torque_nm: float) -> str | None:
    """Why a raw sensor wrench must be rejected, or None if it is usable."""
    if wrench.shape != (6,) or not np.all(np.isfinite(wrench)):
        return 'non-finite wrench'
    if np.linalg.norm(wrench[:3]) > reject_force_n or np.linalg.norm(wrench[3:]) > reject_torque_nm:
        return (
            f'implausible wrench |F| = {np.linalg.norm(wrench[:3]):.3g} N, '
            f'|T| = {np.linalg.norm(wrench[3:]):.3g} N m '
            f'(rejected above {reject_force_n} N / {reject_torque_nm} N m)'
        )
    return None


def deadband_and_clamp(vector: np.ndarray, deadband: float, limit: float) -> np.ndarray:
    """Shrink the magnitude by `deadband` (zero inside it), then cap it at `limit`; direction kept."""
    magnitude = float(np.linalg.norm(vector))
    if magnitude <= deadband:
        return np.zeros_like(vector)
    return vector * (min(magnitude - deadband, limit) / magnitude)


def lowpass_gain(cutoff_hz: float, interval_s: float) -> float:
    """Blend factor of a first-order low-pass for one sample interval (exact discretisation)."""
    return 1.0 - math.exp(-2.0 * math.pi * cutoff_hz * max(interval_s, 0.0))


class WrenchConditioner:
    """Sensor wrench (tool0) -> hand wrench in base_link axes: gravity, bias, low-pass, deadband, clamp.

    Feed it every sensor sample with `add_sample`, read the conditioned wrench with `output`.
    """

    def __init__(self, config: FdccConfig, load: ToolLoad, gravity_base_m_s2: np.ndarray):
        self.config = config
        self.load = load
        self.gravity_base = np.asarray(gravity_base_m_s2, dtype=float)
        self.bias_tool = np.zeros(6)
        self._recent = collections.deque()  # (time s, gravity-compensated tool wrench)
        self._filtered_base: np.ndarray | None = None
        self._last_sample_time_s: float | None = None

    def add_sample(self, wrench_tool: np.ndarray, tool_rotation_base: np.ndarray, time_s: float) -> None:
        """One valid (already checked with `wrench_fault`) sensor sample at the given time."""
        compensated = np.array(wrench_tool, dtype=float)
        if self.config.gravity_compensation:
            compensated -= gravity_wrench_on_tool(self.load, tool_rotation_base, self.gravity_base)
        self._recent.append((time_s, compensated))
        while self._recent and self._recent[0][0] < time_s - self.config.tare_window_s:
            self._recent.popleft()
        hand_tool = compensated - self.bias_tool
        hand_base = np.concatenate([tool_rotation_base @ hand_tool[:3], tool_rotation_base @ hand_tool[3:]])
        last = self._last_sample_time_s
        if self._filtered_base is None or last is None or time_s - last > self.config.watchdog_timeout_s:
            self._filtered_base = hand_base  # after a gap the old state means nothing
        else:
            gain = lowpass_gain(self.config.lowpass_cutoff_hz, time_s - last)
            self._filtered_base = self._filtered_base + gain * (hand_base - self._filtered_base)
        self._last_sample_time_s = time_s

    def can_tare(self, time_s: float) -> bool:
        """True once the tare window holds samples covering at least half of it, the newest one fresh."""
        if not self._recent:
            return False
        newest, oldest = self._recent[-1][0], self._recent[0][0]
        return time_s - newest <= self.config.watchdog_timeout_s and newest - oldest >= 0.5 * self.config.tare_window_s

    def tare(self) -> np.ndarray:
        """Take the mean gravity-compensated reading of the tare window as the sensor bias."""
        if not self._recent:
            raise RuntimeError('no wrench samples to tare with')
        self.bias_tool = np.mean([w for _, w in self._recent], axis=0)
        self._filtered_base = None  # the filter held the old bias: restart it at the next sample
        return self.bias_tool.copy()

    def output(self) -> np.ndarray:
        """Conditioned hand wrench (force N, torque N m) in base_link axes about the tool0 origin."""
        if self._filtered_base is None:
            return np.zeros(6)
        c = self.config
        return np.concatenate(
            [
                deadband_and_clamp(self._filtered_base[:3], c.force_deadband_n, c.max_force_n),
                deadband_and_clamp(self._filtered_base[3:], c.torque_deadband_nm, c.max_torque_nm),
            ]
        )
