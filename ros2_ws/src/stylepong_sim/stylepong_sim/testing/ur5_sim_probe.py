"""A client of `ros2 run stylepong_sim ur5_sim` for system tests: records every topic, calls the services."""

from __future__ import annotations

import dataclasses
import time

import numpy as np
import rclpy
from geometry_msgs.msg import WrenchStamped
from rclpy.experimental import EventsExecutor
from rclpy.qos import QoSProfile
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64MultiArray
from std_srvs.srv import Trigger

from stylepong_common.node_process import wait_until
from stylepong_msgs.msg import BallState, RallyEvent
from stylepong_msgs.srv import LaunchBall


def stamp_s(stamp) -> float:
    """A builtin_interfaces/Time in seconds."""
    return stamp.sec + stamp.nanosec * 1e-9


@dataclasses.dataclass
class Sample:
    """One message as the probe received it."""

    received_s: float  # time.monotonic() at arrival
    stamp_s: float  # header stamp (sim time)
    values: tuple


class Ur5SimProbe:
    """A node beside `ur5_sim` that records its topics and calls its services, for tests and benchmarks."""

    # Deep reader queues: the probe must not lose samples while the test thread is busy.
    QOS = QoSProfile(depth=1000)

    def __init__(self, name: str = 'ur5_sim_probe'):
        self.context = rclpy.Context()
        rclpy.init(context=self.context)
        self.node = rclpy.create_node(name, context=self.context)
        self.executor = EventsExecutor(context=self.context)
        self.executor.add_node(self.node)
        self.joint_states: list[Sample] = []
        self.joint_names: list[str] = []
        self.wrenches: list[Sample] = []
        self.wrench_frames: set[str] = set()
        self.clock: list[Sample] = []
        self.balls: list[Sample] = []
        self.ball_frames: set[str] = set()
        self.events: list[RallyEvent] = []
        node = self.node
        node.create_subscription(JointState, '/joint_states', self._on_joint_state, self.QOS)
        node.create_subscription(WrenchStamped, '/force_torque_sensor_broadcaster/wrench', self._on_wrench, self.QOS)
        node.create_subscription(Clock, '/clock', self._on_clock, self.QOS)
        node.create_subscription(BallState, '/sim/ball/ground_truth', self._on_ball, self.QOS)
        node.create_subscription(RallyEvent, '/rally/events', self.events.append, self.QOS)
        self.command_pub = node.create_publisher(Float64MultiArray, '/forward_position_controller/commands', 10)
        self.hand_pub = node.create_publisher(WrenchStamped, '/sim/hand_wrench', 10)
        self.launch_client = node.create_client(LaunchBall, '/sim/launch_ball')
        self.reset_client = node.create_client(Trigger, '/sim/reset')

    # --- recording ---------------------------------------------------------------------------------
    def _on_joint_state(self, msg: JointState) -> None:
        self.joint_names = list(msg.name)
        self.joint_states.append(
            Sample(
                time.monotonic(),
                stamp_s(msg.header.stamp),
                (np.array(msg.position), np.array(msg.velocity), np.array(msg.effort)),
            )
        )

    def _on_wrench(self, msg: WrenchStamped) -> None:
        self.wrench_frames.add(msg.header.frame_id)
        f, t = msg.wrench.force, msg.wrench.torque
        self.wrenches.append(
            Sample(time.monotonic(), stamp_s(msg.header.stamp), (np.array([f.x, f.y, f.z]), np.array([t.x, t.y, t.z])))
        )

    def _on_clock(self, msg: Clock) -> None:
        self.clock.append(Sample(time.monotonic(), stamp_s(msg.clock), ()))

    def _on_ball(self, msg: BallState) -> None:
        self.ball_frames.add(msg.header.frame_id)
        p, v = msg.position, msg.velocity
        self.balls.append(
            Sample(time.monotonic(), stamp_s(msg.header.stamp), (np.array([p.x, p.y, p.z]), np.array([v.x, v.y, v.z])))
        )

    # --- driving -----------------------------------------------------------------------------------
    def spin_for(self, duration_s: float) -> None:
        deadline = time.monotonic() + duration_s
        while time.monotonic() < deadline:
            self.executor.spin_once(timeout_sec=min(0.01, max(0.0, deadline - time.monotonic())))

    def spin_until(self, predicate, timeout_s: float) -> bool:
        return bool(wait_until(predicate, timeout_s, spin=lambda: self.executor.spin_once(timeout_sec=0.01)))

    def wait_for_sim(self, timeout_s: float = 60.0) -> bool:
        """The node is up: its topics flow and its services and command subscription are matched."""
        return self.spin_until(
            lambda: (
                len(self.joint_states) > 10
                and len(self.wrenches) > 10
                and self.launch_client.service_is_ready()
                and self.reset_client.service_is_ready()
                and self.command_pub.get_subscription_count() > 0
                and self.hand_pub.get_subscription_count() > 0
            ),
            timeout_s,
        )

    def call(self, client, request, timeout_s: float = 20.0):
        future = client.call_async(request)
        self.spin_until(future.done, timeout_s)
        if not future.done():
            raise TimeoutError(f'no answer from {client.srv_name} within {timeout_s} s')
        return future.result()

    def reset(self) -> None:
        assert self.call(self.reset_client, Trigger.Request()).success

    def launch(self, **fields) -> LaunchBall.Response:
        return self.call(self.launch_client, LaunchBall.Request(**fields))

    def command(self, positions) -> None:
        self.command_pub.publish(Float64MultiArray(data=[float(p) for p in positions]))

    def push(self, force_n, frame: str = 'world') -> None:
        msg = WrenchStamped()
        msg.header.frame_id = frame
        msg.wrench.force.x, msg.wrench.force.y, msg.wrench.force.z = (float(f) for f in force_n)
        self.hand_pub.publish(msg)

    def latest_joint_positions(self) -> np.ndarray:
        return self.joint_states[-1].values[0]

    def close(self) -> None:
        self.executor.shutdown()
        self.node.destroy_node()
        rclpy.try_shutdown(context=self.context)
