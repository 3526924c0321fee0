"""Play a recorded demonstration onto the arm, through the player's command limits (`replay_clip`).

    ros2 run stylepong_policy replay_clip ros2_ws/bags/forward_20261123_042746_884 [--speedup 2] [--use-sim-time]

The bag's joint states (any rosbag2 bag build_dataset reads) are resampled to the player's 60 Hz grid,
optionally sped up (the paper's x2/x3/x5 clips), and published on /forward_position_controller/commands:
first a gentle move from where the arm is to the clip's first pose (the player's home-move speed and
acceleration), then the clip, every command through the same CommandLimiter as the player's (URDF
position limits less the margin, velocity per period, acceleration), so a clip too fast for the limits
is slowed there rather than sent. No command while /joint_states is stale. Exits 0 when the clip has
been played, printing how far the commands had to deviate from the clip.
"""

from __future__ import annotations

import argparse
import pathlib
import sys

import numpy as np
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.qos import QoSProfile
from rclpy.utilities import remove_ros_args
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64MultiArray

from stylepong_common.node_support import ThrottledLog, run_node
from stylepong_player import player_core as core
from stylepong_player import spec

ARRIVED_RAD = 1e-6


def load_clip(bag: pathlib.Path, speedup: float, rate_hz: float = spec.ACTION_RATE_HZ) -> np.ndarray:
    """Joint positions [T, 6] (URDF order) of the bag on a rate_hz grid, time compressed by `speedup`."""
    from stylepong_policy.training.dataset import choose_times_ns, drop_repeated, grid_times_s, interpolate_columns
    from stylepong_recording.bag_reading import read_joint_states

    recording = read_joint_states(bag, joints=spec.JOINT_NAMES)
    times_ns, _, _ = choose_times_ns(recording.header_stamp_ns, recording.receive_time_ns)
    keep = drop_repeated(times_ns)
    times_s = (times_ns[keep] - times_ns[keep][0]) * 1e-9 / speedup
    positions = recording.position_rad[keep]
    if len(times_s) < 2 or not np.isfinite(positions).all():
        raise ValueError(f'{bag}: fewer than two usable joint states')
    return interpolate_columns(grid_times_s(float(times_s[-1]), rate_hz), times_s, positions)


class ReplayNode(Node):
    """Moves the arm to a clip's first pose, then plays the clip at 60 Hz within the player's limits."""

    def __init__(self, clip: np.ndarray, use_sim_time: bool):
        super().__init__('replay_clip', parameter_overrides=[Parameter('use_sim_time', value=use_sim_time)])
        config = core.PlayerConfig()
        limits = core.JointLimits.for_commands(
            config.position_margin_rad, config.velocity_limit_scale, config.acceleration_limit_rad_s2
        )
        self.config = config
        self.clip = clip
        self.limiter = core.CommandLimiter(limits, config.period_s)
        self.joint_order = core.JointOrder()
        self.q: np.ndarray | None = None
        self.joint_received_s = -np.inf
        self.index = -1  # -1: moving to the clip's first pose
        self.deviation_rad = 0.0
        self.finished = False
        self.exit_code = 0
        self._warnings = ThrottledLog(self.get_logger())
        qos = QoSProfile(depth=10)
        self._pub = self.create_publisher(Float64MultiArray, '/forward_position_controller/commands', qos)
        self.create_subscription(JointState, '/joint_states', self._on_joint_state, qos)
        self.create_timer(config.period_s, self._on_timer)
        self.get_logger().info(f'replaying {len(clip)} poses ({len(clip) * config.period_s:.2f} s at 60 Hz)')

    def _now_s(self) -> float:
        return self.get_clock().now().nanoseconds * 1e-9

    def _on_joint_state(self, msg: JointState) -> None:
        index = self.joint_order.index(msg.name)
        if index is None or len(msg.position) != len(msg.name):
            self._warnings.warn('joints', 'joint state rejected: it must name every arm joint with a position')
            return
        q = np.asarray(msg.position, dtype=float)[index]
        if np.isfinite(q).all():
            self.q, self.joint_received_s = q, self._now_s()

    def _on_timer(self) -> None:
        if self.finished:
            return
        if (
            self.q is None
            or self._now_s() - self.joint_received_s > self.config.joint_timeout_periods * self.config.period_s
        ):
            self._warnings.warn('stale', 'no fresh /joint_states: no command')
            self.limiter.stop()
            return
        if not self.limiter.active:
            self.limiter.start(self.q)
        if self.index < 0:
            command = self.limiter.step(
                self.clip[0], self.config.home_speed_rad_s, self.config.home_acceleration_rad_s2
            )
            if np.abs(command - self.clip[0]).max() < ARRIVED_RAD and np.abs(self.limiter.velocity_rad_s).max() < 1e-9:
                self.index = 0
                self.get_logger().info('at the first pose: playing the clip')
        else:
            target = self.clip[min(self.index, len(self.clip) - 1)]
            command = self.limiter.step(target)
            self.deviation_rad = max(self.deviation_rad, float(np.abs(command - target).max()))
            self.index += 1
            if self.index >= len(self.clip) and np.abs(self.limiter.velocity_rad_s).max() < 1e-9:
                self.finished = True
                self.get_logger().info(
                    f'clip played; largest deviation of a command from the clip '
                    f'{self.deviation_rad:.4f} rad (the limits)'
                )
        self._pub.publish(Float64MultiArray(data=command.tolist()))


def main(argv: list[str] | None = None) -> int:
    """Entry point of replay_clip: load the bag's clip and play it."""
    argv = sys.argv if argv is None else ['replay_clip', *argv]
    parser = argparse.ArgumentParser(prog='replay_clip', description=__doc__.split('\n\n')[0])
    parser.add_argument('bag', type=pathlib.Path, help='a recorded clip (rosbag2 directory)')
    parser.add_argument('--speedup', type=float, default=1.0, help='play this many times faster (the paper: 2, 3, 5)')
    parser.add_argument('--use-sim-time', action='store_true', help='follow /clock (ur5_sim)')
    args = parser.parse_args(remove_ros_args(argv)[1:])
    if not 0.1 <= args.speedup <= 10.0:
        parser.error('--speedup must be within [0.1, 10]')
    try:
        clip = load_clip(args.bag, args.speedup)
    except Exception as error:  # noqa: BLE001 - BagError, ValueError: any unusable bag is one line
        print(f'replay_clip: {" ".join(str(error).split())}', file=sys.stderr)
        return 2
    return run_node('replay_clip', lambda: ReplayNode(clip, args.use_sim_time), argv)


if __name__ == '__main__':
    sys.exit(main())
