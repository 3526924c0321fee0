"""What the cell's sensors make of the true state: camera and wrist F/T imperfections, and sample clocks.

Free of ROS. Defaults are perfect sensors (no noise, latency, dropout or bias); config/realistic_sensing.yaml
holds realistic levels for robustness tests.
  BallCamera         samples the ball at its rate; each sample is dropped with a probability, otherwise
                     gets Gaussian noise on position and velocity and is delivered `latency_s` after the
                     instant it shows (its stamp).
  ForceTorqueSensor  adds a constant bias and Gaussian noise to the true wrench.
  SampleClock        tells at which physics steps a stream running at rate_hz takes its samples.
"""

from __future__ import annotations

import collections
import math
from dataclasses import dataclass

import numpy as np


def check_nonnegative(name: str, value: float) -> None:
    """ValueError naming the setting `name` unless `value` is finite and >= 0."""
    if not (math.isfinite(value) and value >= 0.0):
        raise ValueError(f'{name} must be finite and >= 0, got {value}')


def check_probability(name: str, value: float) -> None:
    """ValueError naming the setting `name` unless `value` is a probability below 1 (something must get through)."""
    if not 0.0 <= value < 1.0:
        raise ValueError(f'{name} must be in [0, 1), got {value}')


def check_finite_xyz(name: str, value: tuple[float, float, float]) -> None:
    """ValueError naming the setting `name` unless `value` is 3 finite numbers."""
    if len(value) != 3 or not all(math.isfinite(v) for v in value):
        raise ValueError(f'{name} needs 3 finite values, got {list(value)}')


def happens(rng: np.random.Generator, probability: float) -> bool:
    """True with `probability`; at 0 it draws nothing from rng, so a perfect sensor leaves the stream as it was."""
    return probability > 0.0 and rng.random() < probability


@dataclass(frozen=True)
class SensingConfig:
    """Sensor imperfections: ball camera noise, latency and dropout; F/T noise and bias; the seed."""

    ball_position_noise_std_m: float = 0.0
    ball_velocity_noise_std_m_s: float = 0.0
    ball_latency_s: float = 0.0
    ball_dropout_probability: float = 0.0
    ft_force_noise_std_n: float = 0.0
    ft_torque_noise_std_nm: float = 0.0
    ft_force_bias_n: tuple[float, float, float] = (0.0, 0.0, 0.0)
    ft_torque_bias_nm: tuple[float, float, float] = (0.0, 0.0, 0.0)
    seed: int = 0

    def __post_init__(self):
        for name in (
            'ball_position_noise_std_m',
            'ball_velocity_noise_std_m_s',
            'ball_latency_s',
            'ft_force_noise_std_n',
            'ft_torque_noise_std_nm',
        ):
            check_nonnegative(name, getattr(self, name))
        check_probability('ball_dropout_probability', self.ball_dropout_probability)
        for name in ('ft_force_bias_n', 'ft_torque_bias_nm'):
            check_finite_xyz(name, getattr(self, name))


@dataclass(frozen=True)
class BallObservation:
    """A ball camera sample: when it was observed, position and velocity."""

    stamp_s: float  # the instant the observation shows
    position_m: np.ndarray
    velocity_m_s: np.ndarray


class BallCamera:
    """The ball camera: noisy samples, some dropped, delivered after the latency."""

    def __init__(self, config: SensingConfig, rng: np.random.Generator):
        self._config = config
        self._rng = rng
        self._pending: collections.deque[BallObservation] = collections.deque()

    def observe(self, time_s: float, position_m: np.ndarray, velocity_m_s: np.ndarray) -> None:
        c = self._config
        if happens(self._rng, c.ball_dropout_probability):
            return
        position = np.array(position_m, dtype=float)
        velocity = np.array(velocity_m_s, dtype=float)
        if c.ball_position_noise_std_m > 0.0:
            position += self._rng.normal(0.0, c.ball_position_noise_std_m, 3)
        if c.ball_velocity_noise_std_m_s > 0.0:
            velocity += self._rng.normal(0.0, c.ball_velocity_noise_std_m_s, 3)
        self._pending.append(BallObservation(time_s, position, velocity))

    def delivered(self, time_s: float) -> list[BallObservation]:
        """Observations whose latency has passed by time_s, oldest first."""
        out = []
        latency = self._config.ball_latency_s
        while self._pending and self._pending[0].stamp_s + latency <= time_s + 1e-9:
            out.append(self._pending.popleft())
        return out


class ForceTorqueSensor:
    """The wrist F/T sensor: the true wrench plus bias and noise."""

    def __init__(self, config: SensingConfig, rng: np.random.Generator):
        self._config = config
        self._rng = rng
        self._force_bias = np.array(config.ft_force_bias_n, dtype=float)
        self._torque_bias = np.array(config.ft_torque_bias_nm, dtype=float)

    def measure(self, force_n: np.ndarray, torque_nm: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        c = self._config
        force = force_n + self._force_bias
        torque = torque_nm + self._torque_bias
        if c.ft_force_noise_std_n > 0.0:
            force = force + self._rng.normal(0.0, c.ft_force_noise_std_n, 3)
        if c.ft_torque_noise_std_nm > 0.0:
            torque = torque + self._rng.normal(0.0, c.ft_torque_noise_std_nm, 3)
        return force, torque


class SampleClock:
    """Sample instants k / rate_hz; a sample is taken at the first physics step at or after its instant.

    Counting in whole samples (not by adding periods) keeps the long-run rate exact.
    """

    def __init__(self, rate_hz: float, start_s: float = 0.0):
        if not (math.isfinite(rate_hz) and rate_hz > 0.0):
            raise ValueError(f'rate must be positive, got {rate_hz}')
        self.rate_hz = rate_hz
        self._next_index = math.ceil(start_s * rate_hz - 1e-9)

    @property
    def next_s(self) -> float:
        return self._next_index / self.rate_hz

    def due(self, time_s: float) -> bool:
        """True (once) when time_s has reached the next sample instant; later instants already passed
        are skipped, as a camera that was not running would not have taken them."""
        if time_s * self.rate_hz + 1e-6 < self._next_index:
            return False
        self._next_index = math.floor(time_s * self.rate_hz + 1e-6) + 1
        return True
