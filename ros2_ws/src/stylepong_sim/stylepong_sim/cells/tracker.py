"""What a real ball tracker reports: a position per frame, in its camera's frame, stamped at exposure.

Free of ROS. A stereo or multi-camera tracker measures no velocity; it reports the ball's centre once per
frame with a few millimetres of noise, loses some frames, now and then reports something that is not the
ball (a white shoe, a light) and delivers each frame some tens of milliseconds after its exposure.
`BallTracker` does that to the cell's true ball: the velocity and the bounce are left to an estimator
(`stylepong_player.ball_estimator`). Defaults are a perfect tracker; config/tracker_sensing.yaml holds a
150 Hz stereo tracker.

The camera frame `ball_camera` sits where a tracker's reference camera would: beside the table, above it,
looking down at the table's centre. Its pose is a parameter; ur5_sim publishes it on /tf_static.
"""

from __future__ import annotations

import collections
import math
from dataclasses import dataclass

import numpy as np

from stylepong_description.robot_state import quaternion_from_rpy, rotate
from stylepong_sim.cells.sensing import check_finite_xyz, check_nonnegative, check_probability, happens

FRAME_CAMERA = 'ball_camera'
# Table-tennis trackers run their cameras at 120-200 Hz; 150 Hz is no multiple of the player's 60 Hz
# (config/tracker_sensing.yaml says where each figure comes from).
FRAME_RATE_HZ = 150.0
# Beside the table (to the robot's right), 2.5 m up, pitched down towards the table's centre and turned to
# face it: a stereo rig's usual place, clear of the arm and of the ball's flight.
CAMERA_XYZ_M = (0.0, -2.2, 2.6)
CAMERA_RPY_RAD = (0.0, 0.66, 1.5708)
# False detections appear anywhere in this part of the camera's view (world frame, metres): the table
# and the floor around it, up to 2 m.
OUTLIER_BOX_M = ((-3.0, 3.0), (-2.0, 2.0), (0.0, 2.0))


@dataclass(frozen=True)
class TrackerConfig:
    """A tracker's rate and imperfections, and the pose of its camera frame in world."""

    rate_hz: float = FRAME_RATE_HZ
    latency_s: float = 0.0
    latency_jitter_s: float = 0.0
    position_noise_std_m: float = 0.0
    dropout_probability: float = 0.0
    outlier_probability: float = 0.0
    camera_xyz_m: tuple[float, float, float] = CAMERA_XYZ_M
    camera_rpy_rad: tuple[float, float, float] = CAMERA_RPY_RAD

    def __post_init__(self):
        if not (math.isfinite(self.rate_hz) and self.rate_hz > 0.0):
            raise ValueError(f'ball_detection_rate_hz must be positive, got {self.rate_hz}')
        for name in ('latency_s', 'latency_jitter_s', 'position_noise_std_m'):
            check_nonnegative(f'ball_detection_{name}', getattr(self, name))
        if self.latency_jitter_s > self.latency_s:
            raise ValueError(
                f'ball_detection_latency_jitter_s ({self.latency_jitter_s}) must not exceed '
                f'ball_detection_latency_s ({self.latency_s})'
            )
        for name in ('dropout_probability', 'outlier_probability'):
            check_probability(f'ball_detection_{name}', getattr(self, name))
        for name in ('camera_xyz_m', 'camera_rpy_rad'):
            check_finite_xyz(f'ball_{name}', getattr(self, name))

    @property
    def camera_rotation_xyzw(self) -> np.ndarray:
        """The camera frame's orientation in world (a unit quaternion, x y z w)."""
        return quaternion_from_rpy(*self.camera_rpy_rad)


@dataclass(frozen=True)
class Detection:
    """One tracker frame: its exposure instant and the reported centre in the camera frame."""

    stamp_s: float
    position_camera_m: np.ndarray
    delivery_s: float


def world_to_camera(config: TrackerConfig, position_world_m: np.ndarray) -> np.ndarray:
    """A world point in the camera frame."""
    q = config.camera_rotation_xyzw
    inverse = np.array([-q[0], -q[1], -q[2], q[3]])
    return rotate(inverse, np.asarray(position_world_m, dtype=float) - np.asarray(config.camera_xyz_m))


class BallTracker:
    """Detections of the cell's ball: noisy, some lost, some false, delivered after a jittered latency."""

    def __init__(self, config: TrackerConfig, rng: np.random.Generator):
        self.config = config
        self._rng = rng
        self._pending: collections.deque[Detection] = collections.deque()

    def expose(self, time_s: float, ball_position_m: np.ndarray | None) -> None:
        """One frame at time_s, of the ball at ball_position_m (None: no ball in the cell)."""
        c = self.config
        if happens(self._rng, c.outlier_probability):
            low, high = np.array(OUTLIER_BOX_M).T
            self._queue(time_s, self._rng.uniform(low, high))
        if ball_position_m is None:
            return
        if happens(self._rng, c.dropout_probability):
            return
        position = np.array(ball_position_m, dtype=float)
        if c.position_noise_std_m > 0.0:
            position += self._rng.normal(0.0, c.position_noise_std_m, 3)
        self._queue(time_s, position)

    def _queue(self, time_s: float, position_world_m: np.ndarray) -> None:
        c = self.config
        latency_s = c.latency_s
        if c.latency_jitter_s > 0.0:
            latency_s += self._rng.uniform(-c.latency_jitter_s, c.latency_jitter_s)
        # A tracker's pipeline keeps its frames in order: none overtakes the one before it.
        delivery_s = max(time_s + latency_s, self._pending[-1].delivery_s if self._pending else -math.inf)
        self._pending.append(Detection(time_s, world_to_camera(c, position_world_m), delivery_s))

    def delivered(self, time_s: float) -> list[Detection]:
        """Detections whose latency has passed by time_s, in exposure order."""
        out = []
        while self._pending and self._pending[0].delivery_s <= time_s + 1e-9:
            out.append(self._pending.popleft())
        return out


def camera_to_world(config: TrackerConfig, position_camera_m: np.ndarray) -> np.ndarray:
    """A camera-frame point in world (what tf does with the /tf_static transform)."""
    return rotate(config.camera_rotation_xyzw, np.asarray(position_camera_m, dtype=float)) + np.asarray(
        config.camera_xyz_m
    )
