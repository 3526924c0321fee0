"""`ros2 run stylepong_player ball_estimator`: a ball tracker's positions in, the ball's state out.

Subscribes  /ball/detection (geometry_msgs/PointStamped: the ball's centre in the tracker's frame, stamped
            at exposure; remap it to your tracker's topic), /tf_static (tf2_msgs/TFMessage, transient local:
            the tracker's frame in `world`)
Publishes   /ball/state (stylepong_msgs/BallState, frame world, stamp = the detection's exposure; position,
            velocity and their covariances) for each detection once a track is confirmed: the player's input,
            at the tracker's rate. Nothing while no ball is tracked.
            /ball_estimator/status (std_msgs/String, JSON, 1 Hz: published, tentative and rejected counts by
            kind, tracks started)
Parameters  config/ball_estimator.yaml (read at start-up; a bad one: one line on stderr, exit code 2).
Clock       none: the filter runs on the detections' stamps, so start it without use_sim_time (a simulated
            cell's 1 kHz /clock would cost it most of its CPU).
The filter, its gate and its track rules are in ball_estimator.py; detections it refuses are counted and
named in a throttled warning, and never reach /ball/state.
"""

from __future__ import annotations

import collections
import dataclasses
import json
import sys

from geometry_msgs.msg import PointStamped
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from std_msgs.msg import String
from tf2_msgs.msg import TFMessage

from stylepong_common.node_support import Param, ParameterError, ThrottledLog, declare_parameters, run_node
from stylepong_description.robot_cell import FRAME_WORLD
from stylepong_msgs.msg import BallState
from stylepong_player.ball_estimator import BallEstimator, EstimatorConfig, Outcome
from stylepong_player.static_frames import StaticFrames

PROGRAM = 'ball_estimator'
STATUS_PERIOD_S = 1.0
# /tf_static as tf2's static broadcaster offers it: every transform latched for late subscribers.
TF_STATIC_QOS = QoSProfile(
    depth=100, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL
)

_D = EstimatorConfig()
PARAMETERS = (
    Param(
        'measurement_noise_std_m',
        _D.measurement_noise_std_m,
        "the tracker's position noise (std, per axis)",
        low=1e-5,
        high=0.5,
    ),
    Param(
        'acceleration_noise_std_m_s2',
        _D.acceleration_noise_std_m_s2,
        'accelerations the flight model leaves out (spin), as white noise',
        low=1e-3,
        high=100.0,
    ),
    Param(
        'initial_velocity_std_m_s',
        _D.initial_velocity_std_m_s,
        "a new ball's velocity is this uncertain",
        low=0.1,
        high=100.0,
    ),
    Param(
        'bounce_velocity_std_m_s',
        _D.bounce_velocity_std_m_s,
        'velocity uncertainty added at a table bounce',
        low=0.0,
        high=10.0,
    ),
    Param(
        'gate_sigma',
        _D.gate_sigma,
        'detections farther from the prediction (Mahalanobis) are not the ball',
        low=1.0,
        high=100.0,
    ),
    Param(
        'confirm_detections',
        _D.confirm_detections,
        'detections in a row before a new track is published',
        low=2,
        high=100,
    ),
    Param(
        'track_timeout_s', _D.track_timeout_s, 'no detection taken for this long: the ball is lost', low=0.01, high=5.0
    ),
    Param('max_speed_m_s', _D.max_speed_m_s, 'a faster estimate drops the track', low=1.0, high=100.0),
    Param(
        'play_volume_min_m',
        list(_D.play_volume_min_m),
        "world box where a ball may be: lower corner (x: the robot's base, behind it nothing is in play)",
        length=3,
    ),
    Param('play_volume_max_m', list(_D.play_volume_max_m), 'world box where a ball may be: upper corner', length=3),
)


class BallEstimatorNode(Node):
    """Detections -> BallEstimator -> /ball/state."""

    def __init__(self, **node_kwargs):
        super().__init__(PROGRAM, **node_kwargs)
        value = declare_parameters(self, PARAMETERS)
        try:
            # Each field of the config is the parameter of its name; the play volume's corners come as lists.
            settings = {f.name: value[f.name] for f in dataclasses.fields(EstimatorConfig)}
            for corner in ('play_volume_min_m', 'play_volume_max_m'):
                settings[corner] = tuple(settings[corner])
            config = EstimatorConfig(**settings)
            self.estimator = BallEstimator(config)
        except ValueError as error:
            raise ParameterError(str(error)) from error
        self.frames = StaticFrames()
        self.counts: dict[str, int] = collections.defaultdict(int)
        self._warnings = ThrottledLog(self.get_logger())
        self._msg = BallState()
        self._msg.header.frame_id = FRAME_WORLD
        qos = QoSProfile(depth=10)
        self._state_pub = self.create_publisher(BallState, '/ball/state', qos)
        self._status_pub = self.create_publisher(String, '/ball_estimator/status', qos)
        self.create_subscription(TFMessage, '/tf_static', self._on_tf_static, TF_STATIC_QOS)
        # A short queue: if this node falls behind, old frames are dropped rather than estimated late.
        self.create_subscription(PointStamped, '/ball/detection', self._on_detection, QoSProfile(depth=10))
        self.create_timer(STATUS_PERIOD_S, self._publish_status)
        self.get_logger().info('ball estimator: /ball/detection -> /ball/state')

    def _on_tf_static(self, msg: TFMessage) -> None:
        for transform in msg.transforms:
            t, q = transform.transform.translation, transform.transform.rotation
            try:
                self.frames.add(
                    transform.header.frame_id, transform.child_frame_id, (t.x, t.y, t.z), (q.x, q.y, q.z, q.w)
                )
            except ValueError as error:
                self._warnings.warn('tf_static', f'/tf_static: {error}')

    def _on_detection(self, msg: PointStamped) -> None:
        frame = msg.header.frame_id
        p = msg.point
        position = self.frames.to_frame(frame, FRAME_WORLD, (p.x, p.y, p.z))
        if position is None:
            self._reject(
                'frame', f'no transform from {frame!r} to {FRAME_WORLD!r} on /tf_static yet: detection dropped'
            )
            return
        stamp_s = msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9
        result = self.estimator.update(stamp_s, position)
        self.counts[result.outcome.value] += 1
        if result.outcome == Outcome.REJECTED:
            self._reject(result.kind, result.reason)
            return
        if result.outcome == Outcome.PUBLISHED:
            self._publish(result.estimate, msg.header.stamp)

    def _reject(self, kind: str, reason: str) -> None:
        self.counts['rejected_' + kind] += 1
        self._warnings.warn(kind, lambda: f'/ball/detection rejected: {reason}')

    def _publish(self, estimate, stamp) -> None:
        msg = self._msg
        msg.header.stamp = stamp
        msg.position.x, msg.position.y, msg.position.z = estimate.position_m.tolist()
        msg.velocity.x, msg.velocity.y, msg.velocity.z = estimate.velocity_m_s.tolist()
        msg.position_covariance = estimate.covariance[:3, :3].ravel().tolist()
        msg.velocity_covariance = estimate.covariance[3:, 3:].ravel().tolist()
        self._state_pub.publish(msg)

    def status(self) -> str:
        return json.dumps(dict(self.counts, tracks=self.estimator.tracks_started), sort_keys=True)

    def _publish_status(self) -> None:
        self._status_pub.publish(String(data=self.status()))

    def close(self) -> None:
        self.get_logger().info(f'ball estimator: {self.status()}')


def main(args: list[str] | None = None) -> int:
    """Entry point of the ball_estimator executable."""
    return run_node(PROGRAM, BallEstimatorNode, args)


if __name__ == '__main__':
    sys.exit(main())
