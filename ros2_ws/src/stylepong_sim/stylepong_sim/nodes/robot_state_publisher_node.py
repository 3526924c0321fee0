"""`ros2 run stylepong_sim robot_state_publisher`: /robot_description and /tf from /joint_states.

What ROS 2's robot_state_publisher does, for set-ups where it is not installed (it is not published as a
wheel): it publishes the UR5 + paddle URDF (stylepong_description, mesh URIs as file://) on
/robot_description (std_msgs/String, reliable, transient local: a late RViz still gets it), the fixed
joints' transforms on /tf_static (transient local) and, for each /joint_states message, the moving
joints' transforms on /tf, at most publish_frequency times a second (robot_state_publisher's parameter of
that name). /tf_static also places the robot's base_link in the cell's `world` frame (world_spec), so
RViz with fixed frame `world` shows the arm where the table markers are. ur5_sim publishes the same
topics itself (RobotStateOutputs below); this node serves a real arm's /joint_states.

The transforms are computed in stylepong_description.robot_state.
"""

from __future__ import annotations

import math
import sys

from geometry_msgs.msg import TransformStamped
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import JointState
from std_msgs.msg import String
from tf2_msgs.msg import TFMessage

from stylepong_common.node_support import Param, ThrottledLog, declare_parameters, run_node
from stylepong_description import robot_model
from stylepong_description.robot_cell import FRAME_WORLD
from stylepong_description.robot_state import LinkTransform, RobotState, quaternion_from_matrix
from stylepong_sim import world_spec

PROGRAM = 'robot_state_publisher'
# robot_state_publisher's QoS: /robot_description and /tf_static latched (transient local, depth 1);
# /tf keep-last 100 as tf2's broadcaster.
LATCHED_QOS = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL)
TF_QOS = QoSProfile(depth=100)

PARAMETERS = (
    Param(
        'publish_frequency',
        100.0,
        'Most /tf messages per second (each /joint_states above it is skipped)',
        low=1.0,
        high=1000.0,
    ),
)


def base_in_world() -> LinkTransform:
    """world -> base_link: the robot's place in the cell (world_spec)."""
    rotation, position = world_spec.robot_base_pose()
    return LinkTransform(FRAME_WORLD, robot_model.BASE_FRAME, position, quaternion_from_matrix(rotation))


def _to_message(transform: LinkTransform, stamp) -> TransformStamped:
    msg = TransformStamped()
    msg.header.stamp = stamp
    msg.header.frame_id = transform.parent
    msg.child_frame_id = transform.child
    t, q = msg.transform.translation, msg.transform.rotation
    t.x, t.y, t.z = (float(v) for v in transform.translation_m)
    q.x, q.y, q.z, q.w = (float(v) for v in transform.rotation_xyzw)
    return msg


class RobotStateOutputs:
    """The publishers and messages of robot_state_publisher, on a node of the caller's."""

    def __init__(self, node: Node):
        self.urdf_xml = robot_model.urdf_xml_for_display()
        self.state = RobotState(self.urdf_xml)
        self._description_pub = node.create_publisher(String, '/robot_description', LATCHED_QOS)
        self._static_pub = node.create_publisher(TFMessage, '/tf_static', LATCHED_QOS)
        self._tf_pub = node.create_publisher(TFMessage, '/tf', TF_QOS)

    def publish_description_and_static(self, stamp, extra: tuple[LinkTransform, ...] = ()) -> None:
        """Once at start: the URDF and every fixed transform, the robot's and `extra` (a sensor's frame), in one
        latched message (a second /tf_static message from this publisher would replace the first)."""
        self._description_pub.publish(String(data=self.urdf_xml))
        fixed = [base_in_world()] + self.state.fixed_transforms() + list(extra)
        self._static_pub.publish(TFMessage(transforms=[_to_message(t, stamp) for t in fixed]))

    def publish_joint_positions(self, positions_rad, stamp) -> None:
        """The moving joints' transforms, positions in URDF joint order."""
        transforms = self.state.moving_transforms(positions_rad)
        self._tf_pub.publish(TFMessage(transforms=[_to_message(t, stamp) for t in transforms]))

    def publish_joint_state(self, msg: JointState) -> int:
        """The moving joints a JointState names; returns how many it named."""
        transforms = self.state.moving_transforms_by_name(msg.name, msg.position)
        if transforms:
            self._tf_pub.publish(TFMessage(transforms=[_to_message(t, msg.header.stamp) for t in transforms]))
        return len(transforms)


class RobotStatePublisherNode(Node):
    """The robot_state_publisher node: RobotStateOutputs fed by /joint_states, rate-limited by header stamps."""

    def __init__(self, **node_kwargs):
        super().__init__(PROGRAM, **node_kwargs)
        value = declare_parameters(self, PARAMETERS)
        self._min_period_ns = int(1e9 / value['publish_frequency'])
        self._last_published_ns: int | None = None
        self._warnings = ThrottledLog(self.get_logger())
        self._outputs = RobotStateOutputs(self)
        self._outputs.publish_description_and_static(self.get_clock().now().to_msg())
        self.create_subscription(JointState, '/joint_states', self._on_joint_state, QoSProfile(depth=10))
        self.get_logger().info(
            f'publishing /robot_description, /tf_static and /tf (at most '
            f'{value["publish_frequency"]:g} Hz) for {len(self._outputs.state.moving_joints)} '
            'moving joints'
        )

    def _on_joint_state(self, msg: JointState) -> None:
        if len(msg.name) != len(msg.position):
            self._warnings.warn(
                'length', f'/joint_states rejected: {len(msg.name)} names, {len(msg.position)} positions'
            )
            return
        stamp_ns = msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec
        if self._last_published_ns is not None and 0 <= stamp_ns - self._last_published_ns < self._min_period_ns:
            return
        if not all(map(math.isfinite, msg.position)):
            self._warnings.warn('nonfinite', '/joint_states rejected: a position is NaN or infinite')
            return
        if self._outputs.publish_joint_state(msg) == 0:
            self._warnings.warn(
                'names',
                f'/joint_states names none of the URDF joints {", ".join(self._outputs.state.moving_joint_names)}',
            )
            return
        self._last_published_ns = stamp_ns


def main(args: list[str] | None = None) -> int:
    """Entry point of the robot_state_publisher executable."""
    return run_node(PROGRAM, RobotStatePublisherNode, args)


if __name__ == '__main__':
    sys.exit(main())
