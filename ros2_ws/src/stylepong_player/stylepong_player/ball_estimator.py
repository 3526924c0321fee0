"""The ball's state from a tracker's positions: a Kalman filter on the ball's flight, free of ROS.

A tracker reports where the ball is, frame by frame, with noise, lost frames and now and then something
that is not the ball. The actor needs the ball's velocity too. `BallEstimator` keeps one ball's track:

- Flight model: the player's own (`ball_prediction.predict_ball`: gravity, quadratic drag, the table's
  bounce with its restitution and tangential factor), the same constants the simulator uses. The filter
  is filterpy's ExtendedKalmanFilter with its state prediction replaced by that flight; what the model
  leaves out (spin's Magnus force, a bounce that is not the nominal one) is white acceleration noise and,
  at a bounce, extra velocity noise: the bounce resets what the filter believed about the velocity.
- Bounce: the flight predicts it; if a detection misses the gate where a bounce could have happened a
  frame early or late, the bounce is tried at once (`_bounced_prior`) rather than losing the ball.
- Gating: a detection whose Mahalanobis distance from the prediction exceeds gate_sigma is not this ball
  (a false detection, a second ball, a jump); it is counted and leaves the track as it was.
- Tracks: a detection with no track starts a tentative one (velocity unknown); the track is published
  once confirm_detections detections in a row agree with it. A tentative track that a detection misses
  is restarted from that detection (it began on something that was not a ball). A track with no accepted
  detection for track_timeout_s is over: the next ball starts a new one. Detections a confirmed track
  refuses grow a candidate, which takes over if it is confirmed while the track takes nothing: the paddle
  hit the ball, whose new course no flight model foresees, and the player keeps a ball through its stroke.
- Play volume: detections outside it (far away, behind the robot, under the floor) are refused before
  they reach the filter.

Why filterpy: it is the maintained Python Kalman library (EKF, UKF, helpers for process noise) and its
EKF lets the state prediction be any function, which is what a flight with a bounce needs; the
measurement (the position) is linear. Plain numpy around it: a few 6x6 products per detection.
"""

from __future__ import annotations

import enum
import math
from dataclasses import dataclass

import numpy as np
from filterpy.common import Q_continuous_white_noise
from filterpy.kalman import ExtendedKalmanFilter

from stylepong_description import robot_cell
from stylepong_player.ball_prediction import over_table, predict_ball

H = np.hstack([np.eye(3), np.zeros((3, 3))])  # the tracker measures the position


@dataclass(frozen=True)
class EstimatorConfig:
    """The filter's noise model, its gate and track rules, and the volume where a ball may be."""

    measurement_noise_std_m: float = 0.003
    acceleration_noise_std_m_s2: float = 0.5  # the simulated balls do not spin (config/ball_estimator.yaml)
    initial_velocity_std_m_s: float = 8.0  # a new ball may come at any speed the launcher has
    bounce_velocity_std_m_s: float = 0.2  # the bounce model's error per axis (spin, the table's spot)
    gate_sigma: float = 4.0
    confirm_detections: int = 4
    track_timeout_s: float = 0.1
    max_speed_m_s: float = 30.0
    # x from the robot's base (behind it a ball is no longer in play) to past the opponent's end; y beside
    # the table; z from a little under the table top (a ball that fell off the edge) to 2.5 m.
    play_volume_min_m: tuple[float, float, float] = (robot_cell.ROBOT_BASE_POSITION_M[0], -2.0, 0.3)
    play_volume_max_m: tuple[float, float, float] = (robot_cell.HALF_LENGTH_M + 1.5, 2.0, 2.5)

    def validate(self) -> None:
        for name in (
            'measurement_noise_std_m',
            'acceleration_noise_std_m_s2',
            'initial_velocity_std_m_s',
            'bounce_velocity_std_m_s',
            'gate_sigma',
            'track_timeout_s',
            'max_speed_m_s',
        ):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0.0):
                raise ValueError(f'{name} must be finite and positive, got {value}')
        if self.confirm_detections < 2:
            raise ValueError(f'confirm_detections must be at least 2, got {self.confirm_detections}')
        low, high = np.array(self.play_volume_min_m), np.array(self.play_volume_max_m)
        if (
            low.shape != (3,)
            or high.shape != (3,)
            or not (np.isfinite(low).all() and np.isfinite(high).all() and (low < high).all())
        ):
            raise ValueError(
                f'play volume needs 3 finite bounds with min < max, got {low.tolist()} and {high.tolist()}'
            )


class Outcome(str, enum.Enum):
    """What a detection did."""

    PUBLISHED = 'published'  # the track is confirmed: an estimate at the detection's stamp
    TENTATIVE = 'tentative'  # taken, the track is not confirmed yet (nothing to publish)
    REJECTED = 'rejected'  # refused (see the reason)


@dataclass(frozen=True)
class Estimate:
    """The ball at a detection's stamp: position, velocity and their 6x6 covariance (world frame)."""

    stamp_s: float
    position_m: np.ndarray
    velocity_m_s: np.ndarray
    covariance: np.ndarray

    @property
    def velocity_std_m_s(self) -> float:
        """The largest per-axis standard deviation of the velocity."""
        return float(np.sqrt(np.max(np.diag(self.covariance)[3:])))


@dataclass(frozen=True)
class Result:
    """What one detection did: its outcome, the estimate it led to (if any) and why it was rejected."""

    outcome: Outcome
    estimate: Estimate | None = None
    kind: str = ''  # why it was rejected, a short key for counters and throttled warnings
    reason: str = ''


class _FlightFilter(ExtendedKalmanFilter):
    """filterpy's EKF whose state prediction is the ball's flight over `dt_s` (set before predict)."""

    def __init__(self):
        super().__init__(dim_x=6, dim_z=3)
        self.dt_s = 0.0
        self.bounced = False

    def predict_x(self, u=0):
        p, v = self.x[:3, 0], self.x[3:, 0]
        p_next, v_next = predict_ball(p, v, self.dt_s)
        self.bounced = v[2] < 0.0 < v_next[2]  # gravity alone never turns a fall into a rise
        self.x = np.concatenate([p_next, v_next]).reshape(6, 1)


def _transition(dt_s: float, bounced: bool) -> np.ndarray:
    """The flight's Jacobian to first order: positions move with the velocity; a bounce scales it."""
    scale = (
        np.array(
            [robot_cell.TABLE_TANGENTIAL_FACTOR, robot_cell.TABLE_TANGENTIAL_FACTOR, -robot_cell.TABLE_RESTITUTION]
        )
        if bounced
        else np.ones(3)
    )
    f = np.eye(6)
    f[:3, 3:] = dt_s * np.eye(3)
    f[3:, 3:] = np.diag(scale)
    return f


def _mahalanobis(kf: ExtendedKalmanFilter, z: np.ndarray, r: np.ndarray) -> float:
    y = z - H @ kf.x
    s = H @ kf.P @ H.T + r
    return float(np.sqrt((y.T @ np.linalg.solve(s, y)).item()))


class _Track:
    """One hypothesis of a ball: its filter, its clock and how many detections it has taken."""

    def __init__(self, config: EstimatorConfig, stamp_s: float, z: np.ndarray):
        self.config = config
        self.kf = _FlightFilter()
        self.kf.x = np.vstack([z, np.zeros((3, 1))])
        self.kf.P = np.diag([config.measurement_noise_std_m**2] * 3 + [config.initial_velocity_std_m_s**2] * 3)
        self.stamp_s = self.accepted_s = stamp_s
        self.hits = 1

    @property
    def confirmed(self) -> bool:
        return self.hits >= self.config.confirm_detections

    def timed_out(self, stamp_s: float) -> bool:
        return stamp_s - self.accepted_s > self.config.track_timeout_s

    def predict(self, stamp_s: float) -> None:
        """The flight to stamp_s (no change for a second detection of the same frame)."""
        kf, dt_s = self.kf, stamp_s - self.stamp_s
        if dt_s <= 0.0:
            return
        kf.dt_s = dt_s
        kf.Q = Q_continuous_white_noise(
            dim=2,
            dt=dt_s,
            spectral_density=self.config.acceleration_noise_std_m_s2**2,
            block_size=3,
            order_by_dim=False,
        )
        covariance = kf.P
        kf.predict_x()
        kf.F = _transition(dt_s, kf.bounced)  # the Jacobian is known once the flight says whether it bounced
        kf.P = kf.F @ covariance @ kf.F.T + kf.Q
        if kf.bounced:
            kf.P[3:, 3:] += np.eye(3) * self.config.bounce_velocity_std_m_s**2
        self.stamp_s = stamp_s

    def take(self, z: np.ndarray, r: np.ndarray) -> float:
        """Update with z if it lies within the gate (trying a bounce the flight missed); else leave the
        filter as predicted. Returns the Mahalanobis distance of z (0 when taken)."""
        distance = _mahalanobis(self.kf, z, r)
        if distance > self.config.gate_sigma:
            bounced = self._bounced_prior()
            if bounced is None or _mahalanobis(bounced, z, r) > self.config.gate_sigma:
                return distance
            self.kf = bounced
        self.kf.update(z, lambda _x: H, lambda x: H @ x, R=r)
        self.accepted_s = self.stamp_s
        self.hits += 1
        return 0.0

    def estimate(self) -> Estimate:
        x = self.kf.x[:, 0]
        return Estimate(self.stamp_s, x[:3].copy(), x[3:].copy(), self.kf.P.copy())

    def _bounced_prior(self) -> _FlightFilter | None:
        """The prediction with a bounce it did not have (the ball met the table a frame before the model
        said), or None where no bounce could have happened: over the table, falling, near its top."""
        kf = self.kf
        p, v = kf.x[:3, 0], kf.x[3:, 0]
        if kf.bounced or v[2] >= 0.0 or not over_table(p[0], p[1]):
            return None
        if p[2] - robot_cell.TABLE_CONTACT_HEIGHT_M > abs(v[2]) * 0.02 + 0.01:
            return None
        f = _transition(0.0, True)
        bounced = _FlightFilter()
        bounced.x = f @ kf.x
        bounced.x[2, 0] = max(p[2], robot_cell.TABLE_CONTACT_HEIGHT_M)  # on or over the table, rising
        bounced.P = f @ kf.P @ f.T
        bounced.P[3:, 3:] += np.eye(3) * self.config.bounce_velocity_std_m_s**2
        bounced.bounced = True
        return bounced


class BallEstimator:
    """The ball's track from stamped world positions: feed detections in stamp order to `update` (several may
    share a stamp: a frame with the ball and a false detection).

    Beside the published track a candidate grows from the detections it refuses. If the candidate is
    confirmed while the track has taken nothing since the candidate began, the ball changed course where
    no flight model says (the paddle hit it) or the old ball is gone and another came: the candidate becomes
    the track. A second ball seen beside the first never does: the first keeps taking its detections.
    """

    def __init__(self, config: EstimatorConfig | None = None):
        self.config = config or EstimatorConfig()
        self.config.validate()
        self._r = np.eye(3) * self.config.measurement_noise_std_m**2
        # The play volume as arrays once, not per detection.
        self._low = np.array(self.config.play_volume_min_m)
        self._high = np.array(self.config.play_volume_max_m)
        self._track: _Track | None = None
        self._candidate: _Track | None = None
        self._stamp_s = -math.inf  # the latest detection's stamp
        self.tracks_started = 0

    @property
    def confirmed(self) -> bool:
        return self._track is not None and self._track.confirmed

    def update(self, stamp_s: float, position_m) -> Result:
        """One detection (exposure stamp, world position). Stamps must not decrease."""
        z = np.asarray(position_m, dtype=float).reshape(3, 1)
        if not (math.isfinite(stamp_s) and np.isfinite(z).all()):
            return _rejected('not_finite', 'detection has NaN or inf')
        problem = self._outside_play_volume(z[:, 0])
        if problem:
            return problem
        if stamp_s < self._stamp_s:  # equal stamps: more than one detection in a frame (the ball, a false one)
            return _rejected('stamp_order', f'detection stamp {stamp_s:.4f} s is before the last {self._stamp_s:.4f} s')
        self._stamp_s = stamp_s
        track = self._track
        if track is None or track.timed_out(stamp_s):  # lost (or the tracker stopped): a new ball
            self._start(stamp_s, z)
            return Result(Outcome.TENTATIVE)
        track.predict(stamp_s)
        distance = track.take(z, self._r)
        if distance == 0.0:
            self._candidate = None
            return self._published(track)
        if not track.confirmed:
            self._start(stamp_s, z)  # the track began on something that was not a ball
            return Result(Outcome.TENTATIVE)
        if self._grow_candidate(stamp_s, z):
            self._track, self._candidate = self._candidate, None
            self.tracks_started += 1
            return self._published(self._track)
        return _rejected(
            'gated',
            f'detection {np.round(z[:, 0], 3).tolist()} m is {distance:.1f} sigma from the '
            'ball (a false detection, a second ball or a jump)',
        )

    # --- internals -------------------------------------------------------------------------------
    def _start(self, stamp_s: float, z: np.ndarray) -> None:
        self._track, self._candidate = _Track(self.config, stamp_s, z), None
        self.tracks_started += 1

    def _grow_candidate(self, stamp_s: float, z: np.ndarray) -> bool:
        """A refused detection feeds the candidate (or starts one); whether the candidate is now confirmed."""
        candidate = self._candidate
        if candidate is None or candidate.timed_out(stamp_s):
            self._candidate = _Track(self.config, stamp_s, z)
            return False
        candidate.predict(stamp_s)
        if candidate.take(z, self._r) != 0.0:
            self._candidate = _Track(self.config, stamp_s, z)
            return False
        return candidate.confirmed

    def _published(self, track: _Track) -> Result:
        if not track.confirmed:
            return Result(Outcome.TENTATIVE)
        estimate = track.estimate()
        speed = float(np.linalg.norm(estimate.velocity_m_s))
        if speed > self.config.max_speed_m_s:
            self._track = self._candidate = None
            return _rejected('speed', f'estimated speed {speed:.1f} m/s is implausible: track dropped')
        return Result(Outcome.PUBLISHED, estimate)

    def _outside_play_volume(self, p: np.ndarray) -> Result | None:
        if (self._low <= p).all() and (p <= self._high).all():
            return None
        if p[0] < self._low[0]:
            return _rejected('behind_robot', f'detection {np.round(p, 2).tolist()} m is behind the robot')
        return _rejected('outside', f'detection {np.round(p, 2).tolist()} m is outside the play volume')


def _rejected(kind: str, reason: str) -> Result:
    return Result(Outcome.REJECTED, kind=kind, reason=reason)
