"""`ros2 run stylepong_recording recorder`: records labelled demonstration clips into rosbag2 bags.

Services: `/recorder/start` (stylepong_msgs/srv/StartClip: label -> success, bag_path, message) opens
`<output_dir>/<label>_<time>/`; `/recorder/stop` (std_srvs/Trigger) closes it. Recorded: /joint_states
plus the `topics` parameter (types found in the graph; a topic not published yet is picked up when it
appears). Each message is stored as received (serialized, header stamps untouched) with its receive
time (the middleware's reception timestamp, system clock) as the bag's log time. Any joint-state source
will do: ur5_sim under drag_teach, or a real robot's driver while a person moves the arm with its
teach pendant.

The subscriptions stay up while the node runs, so a clip starts with the very next message received;
messages received between clips (or before a clip started and only taken from the queue after) are
dropped. Subscriptions are reliable with a deep queue (`queue_depth`), best effort only for a topic
whose publishers offer nothing better. Parameters: PARAMETERS below, defaults in config/recorder.yaml;
a bad one stops the node with one line on stderr and exit code 2 (stylepong_common.node_support).
Writing and crash safety are in clip_writer; this module is wiring.
"""

from __future__ import annotations

import importlib
import sys
import time
from pathlib import Path
from typing import Any

from rclpy.duration import Duration
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from rosbags.interfaces import Qos, QosDurability, QosHistory, QosLiveliness, QosReliability, QosTime
from std_srvs.srv import Trigger

from stylepong_common.node_support import Param, ParameterError, ThrottledLog, declare_parameters, run_node
from stylepong_msgs.srv import StartClip
from stylepong_recording.bag_layout import MCAP_STORAGE, STORAGES
from stylepong_recording.clip_writer import DEFAULT_FLUSH_PERIOD_S, ClipError, ClipWriter, TopicSpec, open_clip
from stylepong_recording.msg_definitions import MessageDefinitions, UnknownMessageType

PROGRAM = 'recorder'
JOINT_STATES_TOPIC = '/joint_states'
JOINT_STATES_TYPE = 'sensor_msgs/msg/JointState'
MAX_FLUSH_PERIOD_S = 0.2  # the recorder's promise: a SIGKILL loses at most this much
DISCOVERY_PERIOD_S = 1.0
# A topic published with several types is named at most this often while it stays so.
SEVERAL_TYPES_WARN_PERIOD_S = 30.0

PARAMETERS = (
    Param(
        'output_dir',
        'ros2_ws/bags',
        'where clips go; a relative path is taken from the directory holding the colcon workspace (the project root)',
    ),
    Param('storage', MCAP_STORAGE, 'bag storage format', choices=STORAGES),
    Param(
        'flush_period_s',
        DEFAULT_FLUSH_PERIOD_S,
        'seconds between hand-overs of written data to the OS; a SIGKILL loses at most about this much',
        low=0.01,
        high=MAX_FLUSH_PERIOD_S,
    ),
    Param(
        'queue_depth',
        1000,
        'subscription queue depth per topic (messages kept while the node is busy)',
        low=10,
        high=100000,
    ),
    Param(
        'min_free_space_mb', 100.0, 'a clip does not start with less free disk space than this (MB)', low=0.0, high=1e9
    ),
    # An empty default: rcl cannot parse an empty list from a parameters file, so the YAML leaves it out.
    Param('topics', [], 'topics recorded besides /joint_states (types found in the graph)'),
)


def resolve_output_dir(output_dir: str, install_prefix: Path | None, cwd: Path) -> Path:
    """An absolute output_dir as given; a relative one against the directory holding the colcon
    workspace the recorder was installed from (the project root, so `ros2_ws/bags` is the shipped
    clips' folder whatever the current directory), or against `cwd` outside a colcon workspace."""
    path = Path(output_dir).expanduser()
    if path.is_absolute():
        return path
    base = cwd
    if install_prefix is not None:
        if install_prefix.parent.name == 'install':  # isolated install: <ws>/install/<pkg>
            base = install_prefix.parent.parent.parent
        elif install_prefix.name == 'install':  # merged install: <ws>/install
            base = install_prefix.parent.parent
    return base / path


def rosbags_qos(profile: QoSProfile) -> Qos:
    """A publisher's offered QoS in the form rosbag2 metadata stores (enum values are rmw's)."""

    def duration(d: Duration) -> QosTime:
        sec, nsec = divmod(d.nanoseconds, 1_000_000_000)
        return QosTime(sec, nsec)

    return Qos(
        QosHistory(int(profile.history)),
        int(profile.depth),
        QosReliability(int(profile.reliability)),
        QosDurability(int(profile.durability)),
        duration(profile.deadline),
        duration(profile.lifespan),
        QosLiveliness(int(profile.liveliness)),
        duration(profile.liveliness_lease_duration),
        bool(profile.avoid_ros_namespace_conventions),
    )


def subscription_reliability(offered: list[ReliabilityPolicy]) -> ReliabilityPolicy:
    """Reliable (no drops) unless a publisher only offers best effort, which a reliable reader
    would not match at all."""
    return ReliabilityPolicy.BEST_EFFORT if ReliabilityPolicy.BEST_EFFORT in offered else ReliabilityPolicy.RELIABLE


def extra_topics(value: list[Any]) -> list[str]:
    """The `topics` parameter as topic names; ParameterError unless it is a list of strings."""
    if not all(isinstance(topic, str) for topic in value):
        raise ParameterError(f'parameter topics must be a list of topic names, got {value!r}')
    return list(value)


def output_dir_path(output_dir: str) -> Path:
    """Where clips go: resolve_output_dir against this package's install prefix and the current directory."""
    if not output_dir:
        raise ParameterError(f'parameter output_dir must not be empty, got {output_dir!r}')
    try:
        from ament_index_python.packages import get_package_prefix

        prefix = Path(get_package_prefix('stylepong_recording'))
    except Exception:  # noqa: BLE001 - not installed through an ament index: fall back to cwd
        prefix = None
    return resolve_output_dir(output_dir, prefix, Path.cwd())


def message_class(msgtype: str):
    """The Python message class of a type name such as 'sensor_msgs/msg/JointState'."""
    package, kind, name = msgtype.split('/')
    return getattr(importlib.import_module(f'{package}.{kind}'), name)


class RecorderNode(Node):
    """The recorder node: writes /joint_states (and any extra topics) of each clip to a rosbag2 bag."""

    def __init__(self, **kwargs):
        super().__init__(PROGRAM, **kwargs)
        values = declare_parameters(self, PARAMETERS)
        self.output_dir = output_dir_path(values['output_dir'])
        self.storage = values['storage']
        self.flush_period_s = values['flush_period_s']
        self.queue_depth = values['queue_depth']
        self.min_free_space_mb = values['min_free_space_mb']
        extra = extra_topics(values['topics'])
        self.warnings = ThrottledLog(self.get_logger(), period_s=SEVERAL_TYPES_WARN_PERIOD_S)
        # Resolved (namespace, remapping) names: what the graph and the bag call them.
        self.joint_states_topic = self.resolve_topic_name(JOINT_STATES_TOPIC)
        self.topics = list(dict.fromkeys([self.joint_states_topic, *map(self.resolve_topic_name, extra)]))

        self._definitions = MessageDefinitions()
        self._recorded: dict[str, tuple[object, str, ReliabilityPolicy]] = {}
        self._clip: ClipWriter | None = None
        self._clip_label = ''
        self._clip_start_ns = 0
        self._failure: str | None = None

        self._subscribe(self.joint_states_topic, JOINT_STATES_TYPE)
        self._discover()
        self.create_timer(DISCOVERY_PERIOD_S, self._discover)
        # Flushes also happen on writes; the timer covers a clip whose topics fall silent.
        self.create_timer(self.flush_period_s / 2.0, self._flush_if_due)
        self.create_service(StartClip, '~/start', self._on_start)
        self.create_service(Trigger, '~/stop', self._on_stop)
        name = self.get_fully_qualified_name()
        self.get_logger().info(
            f'ready: {name}/start and {name}/stop record {", ".join(self.topics)} into '
            f'{self.output_dir} ({self.storage}, flushed every {self.flush_period_s:g} s)'
        )

    # --- subscriptions ------------------------------------------------------------------------------
    def _publisher_qos(self, topic: str) -> list[QoSProfile]:
        return [info.qos_profile for info in self.get_publishers_info_by_topic(topic)]

    def _subscribe(self, topic: str, msgtype: str) -> None:
        try:
            self._definitions.definition(msgtype)
            msg_class = message_class(msgtype)
        except (UnknownMessageType, ImportError, AttributeError, ValueError) as err:
            self.get_logger().error(f'cannot record {topic} ({msgtype}): {err}', once=True)
            return
        reliability = subscription_reliability([q.reliability for q in self._publisher_qos(topic)])
        qos = QoSProfile(
            history=HistoryPolicy.KEEP_LAST,
            depth=self.queue_depth,
            reliability=reliability,
            durability=DurabilityPolicy.VOLATILE,
        )
        subscription = self.create_subscription(
            msg_class, topic, lambda data, info: self._on_message(topic, data, info), qos, raw=True
        )
        self._recorded[topic] = (subscription, msgtype, reliability)

    def _discover(self) -> None:
        """Subscribe to requested topics once they appear; follow publishers' reliability."""
        graph = dict(self.get_topic_names_and_types())
        for topic in self.topics:
            if topic in self._recorded:
                subscription, msgtype, reliability = self._recorded[topic]
                wanted = subscription_reliability([q.reliability for q in self._publisher_qos(topic)])
                if wanted != reliability:
                    self.get_logger().info(f'{topic}: publishers offer {wanted.name.lower()}; resubscribing')
                    self.destroy_subscription(subscription)
                    self._subscribe(topic, msgtype)
            elif topic in graph:
                types = graph[topic]
                if len(types) != 1:
                    self.warnings.warn(f'several types {topic}', f'{topic} has several types {types}; not recorded')
                    continue
                self._subscribe(topic, types[0])
                if topic in self._recorded:
                    self.get_logger().info(f'recording {topic} ({types[0]}) from now on')

    def _topic_spec(self, topic: str) -> TopicSpec:
        msgtype = self._recorded[topic][1]
        msgdef, rihs01 = self._definitions.definition(msgtype)
        offered = tuple(rosbags_qos(q) for q in self._publisher_qos(topic))
        return TopicSpec(topic, msgtype, msgdef, rihs01, offered)

    # --- recording ----------------------------------------------------------------------------------
    def _on_message(self, topic: str, data: bytes, info: dict) -> None:
        clip = self._clip
        if clip is None:
            return
        # The middleware's reception time is free of executor delays; 0 where an rmw does not fill it.
        log_time_ns = info.get('received_timestamp') or time.time_ns()
        if log_time_ns < self._clip_start_ns:
            return  # received before the clip started, taken from the queue only now
        try:
            if not clip.has_topic(topic):
                clip.add_topic(self._topic_spec(topic))
            clip.write(topic, log_time_ns, data)
        except ClipError as err:
            self._clip_failed(str(err))

    def _flush_if_due(self) -> None:
        if self._clip is not None:
            try:
                self._clip.flush_if_due()
            except ClipError as err:
                self._clip_failed(str(err))

    def _clip_failed(self, reason: str) -> None:
        self.get_logger().error(f'clip {self._clip_label!r} stopped: {reason}')
        self._failure = reason
        self._clip = None

    def _on_start(self, request: StartClip.Request, response: StartClip.Response) -> StartClip.Response:
        if self._clip is not None:
            response.success = False
            response.bag_path = str(self._clip.bag_dir)
            response.message = (
                f'already recording {self._clip_label!r} into {self._clip.bag_dir}; call /recorder/stop first'
            )
            return response
        try:
            specs = [self._topic_spec(topic) for topic in self._recorded]
            self._clip_start_ns = time.time_ns()
            self._clip = open_clip(
                self.output_dir, request.label, self.storage, specs, self.flush_period_s, self.min_free_space_mb
            )
        except ClipError as err:
            response.success = False
            response.message = f'not recording: {err}'
            self.get_logger().warn(response.message)
            return response
        self._clip_label = request.label
        self._failure = None
        waiting = [t for t in self.topics if t not in self._recorded]
        response.success = True
        response.bag_path = str(self._clip.bag_dir)
        response.message = f'recording {request.label!r} into {self._clip.bag_dir}'
        if waiting:
            response.message += f' (not published yet: {", ".join(waiting)})'
        self.get_logger().info(response.message)
        return response

    def _on_stop(self, request: Trigger.Request, response: Trigger.Response) -> Trigger.Response:
        if self._clip is None:
            response.success = False
            if self._failure is not None:
                response.message = f'the clip had already stopped: {self._failure}'
                self._failure = None
            else:
                response.message = 'not recording'
            return response
        response.success, response.message = self.close_clip()
        return response

    def close_clip(self) -> tuple[bool, str]:
        """Close the open clip, if any: (whether it was saved, what happened)."""
        clip, self._clip = self._clip, None
        if clip is None:
            return True, 'not recording'
        try:
            summary = clip.close()
        except ClipError as err:
            self.get_logger().error(str(err))
            return False, str(err)
        message = f'saved {self._clip_label!r}: {summary.describe()}'
        self.get_logger().info(message)
        return True, message

    def close(self) -> None:
        """On the way out (Ctrl-C, SIGTERM; stylepong_common.node_support.run_node): a clip still open is
        closed properly, with its summary, footer and metadata.yaml."""
        self.close_clip()


def main(args: list[str] | None = None) -> int:
    """Entry point of the recorder executable."""
    # The single-threaded executor, the one rclpy.spin uses: the receive times come with the message info,
    # which rclpy 7.1's events executor cannot hand to a callback.
    return run_node(PROGRAM, RecorderNode, args, make_executor=SingleThreadedExecutor)


if __name__ == '__main__':
    sys.exit(main())
