"""Write JointState recordings for tests and benchmarks, the way real writers do.

* `write_recorder_bag`: rosbags' Writer, mcap (or sqlite3), the label in custom_data and a
  `<label>_<time>` directory: how StylePong's recorder stores a teaching clip.
* `write_driver_bag`: another writer (the `mcap` + `mcap-ros2-support` libraries, not rosbags) in the
  style of a real UR driver: driver joint order plus a gripper joint, 125 Hz header stamps with bursty
  receive times, empty velocity arrays, and a metadata.yaml as rosbag2 (Jazzy) writes it.
* `truncate_file`: cut a storage file short, as a recorder killed mid-write leaves it.

Motions are given as functions of time returning (position, velocity) in URDF joint order.
"""

from __future__ import annotations

import math
import pathlib
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from stylepong_description.robot_model import JOINT_NAMES as URDF_JOINTS

# The order ur_robot_driver's joint_state_broadcaster publishes (seen in real UR3e recordings).
DRIVER_JOINTS = (
    'shoulder_lift_joint',
    'elbow_joint',
    'wrist_1_joint',
    'wrist_2_joint',
    'wrist_3_joint',
    'shoulder_pan_joint',
)
GRIPPER_JOINT = 'robotiq_85_left_knuckle_joint'
EPOCH_NS = 1_763_700_000_000_000_000  # a date in 2025, as a real recording would carry
DRIVER_RATE_HZ = 125.0  # write_driver_bag's header stamps, as the driver recordings it imitates

Motion = Callable[[np.ndarray], tuple[np.ndarray, np.ndarray]]


def min_jerk(tau: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Minimum-jerk profile s(tau) on [0, 1] and its first two derivatives (held flat outside)."""
    tau = np.clip(tau, 0.0, 1.0)
    s = 10 * tau**3 - 15 * tau**4 + 6 * tau**5
    ds = 30 * tau**2 - 60 * tau**3 + 30 * tau**4
    dds = 60 * tau - 180 * tau**2 + 120 * tau**3
    return s, ds, dds


@dataclass(frozen=True)
class Swing:
    """Rest, one minimum-jerk swing from start to end, rest: a demonstration-like motion."""

    start_rad: tuple[float, ...] = (0.0, -1.9, 1.7, -1.4, -1.6, 2.8)
    end_rad: tuple[float, ...] = (0.6, -1.3, 1.1, -0.8, -1.2, 4.1)  # wrist_3 turns past pi
    rest_before_s: float = 0.5
    duration_s: float = 1.5
    rest_after_s: float = 0.5

    @property
    def total_s(self) -> float:
        return self.rest_before_s + self.duration_s + self.rest_after_s

    def __call__(self, t_s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        t_s = np.asarray(t_s, dtype=float)
        tau = (t_s - self.rest_before_s) / self.duration_s
        s, ds, _ = min_jerk(tau)
        moving = (tau > 0) & (tau < 1)
        delta = np.asarray(self.end_rad) - np.asarray(self.start_rad)
        q = np.asarray(self.start_rad) + s[:, None] * delta
        qd = np.where(moving, ds, 0.0)[:, None] * delta / self.duration_s
        return q, qd


def wrap_to_pi(angle_rad: np.ndarray) -> np.ndarray:
    """[-pi, pi), as a driver that reports a continuous joint modulo one turn."""
    return (np.asarray(angle_rad) + math.pi) % (2 * math.pi) - math.pi


def sample_times_s(duration_s: float, rate_hz: float) -> np.ndarray:
    """A recording's sample instants from 0: every 1/rate_hz up to duration_s, both ends included."""
    return np.arange(int(round(duration_s * rate_hz)) + 1) / rate_hz


def _storage_plugin(storage: str):
    """rosbags' storage plugin called `storage` ('mcap' or 'sqlite3')."""
    from rosbags.rosbag2.enums import StoragePlugin

    return {'mcap': StoragePlugin.MCAP, 'sqlite3': StoragePlugin.SQLITE3}[storage]


def jazzy_typestore():
    """rosbags' ROS 2 Jazzy type store."""
    from rosbags.typesys import Stores, get_typestore

    return get_typestore(Stores.ROS2_JAZZY)


def joint_state_cdr(
    store,
    stamp_ns: int,
    names: Sequence[str],
    position,
    velocity=(),
    effort=(),
    frame_id: str = '',
    little_endian: bool = True,
) -> bytes:
    """A sensor_msgs/JointState serialized by rosbags (CDR, either byte order)."""
    msgs = store.types
    message = msgs['sensor_msgs/msg/JointState'](
        header=msgs['std_msgs/msg/Header'](
            stamp=msgs['builtin_interfaces/msg/Time'](
                sec=int(stamp_ns // 1_000_000_000), nanosec=int(stamp_ns % 1_000_000_000)
            ),
            frame_id=frame_id,
        ),
        name=list(names),
        position=np.asarray(position, dtype=np.float64),
        velocity=np.asarray(velocity, dtype=np.float64),
        effort=np.asarray(effort, dtype=np.float64),
    )
    return bytes(store.serialize_cdr(message, 'sensor_msgs/msg/JointState', little_endian=little_endian))


def write_recorder_bag(
    bag_dir: pathlib.Path,
    motion: Motion,
    duration_s: float,
    *,
    rate_hz: float = 500.0,
    label: str | None = 'forward',
    storage: str = 'mcap',
    topic: str = '/joint_states',
    compression: str | None = None,
    start_ns: int = EPOCH_NS,
    raw_messages: Callable[[int, bytes], bytes] | None = None,
) -> int:
    """A bag as StylePong's recorder writes it (rosbags Writer); returns the number of messages.

    raw_messages(index, cdr) may replace a message's bytes (to plant a corrupt one).
    """
    from rosbags.rosbag2 import Writer
    from rosbags.rosbag2.enums import CompressionFormat, CompressionMode

    store = jazzy_typestore()
    times_s = sample_times_s(duration_s, rate_hz)
    q, qd = motion(times_s)
    writer = Writer(bag_dir, version=9, storage_plugin=_storage_plugin(storage))
    if compression:
        writer.set_compression(CompressionMode[compression.upper()], CompressionFormat.ZSTD)
    with writer:
        if label is not None:
            writer.set_custom_data('label', label)
        connection = writer.add_connection(topic, 'sensor_msgs/msg/JointState', typestore=store)
        for i, t_s in enumerate(times_s):
            stamp_ns = start_ns + int(round(t_s * 1e9))
            raw = joint_state_cdr(store, stamp_ns, URDF_JOINTS, q[i], qd[i], np.zeros(6))
            if raw_messages is not None:
                raw = raw_messages(i, raw)
            writer.write(connection, stamp_ns + 300_000, raw)
    return len(times_s)


def write_raw_bag(
    bag_dir: pathlib.Path,
    topics: dict[str, Sequence[tuple[int, bytes]]],
    *,
    storage: str = 'mcap',
    msgtypes: dict[str, str] | None = None,
    label: str | None = None,
) -> None:
    """A bag (rosbags Writer) holding exactly these (receive_ns, serialized bytes) messages per topic."""
    from rosbags.rosbag2 import Writer

    store = jazzy_typestore()
    with Writer(bag_dir, version=9, storage_plugin=_storage_plugin(storage)) as writer:
        if label is not None:
            writer.set_custom_data('label', label)
        for topic, messages in topics.items():
            msgtype = (msgtypes or {}).get(topic, 'sensor_msgs/msg/JointState')
            connection = writer.add_connection(topic, msgtype, typestore=store)
            for receive_ns, raw in messages:
                writer.write(connection, int(receive_ns), raw)


QOS_YAML = """- history: keep_last
  depth: 10
  reliability: reliable
  durability: volatile
  deadline:
    sec: 9223372036
    nsec: 854775807
  lifespan:
    sec: 9223372036
    nsec: 854775807
  liveliness: automatic
  liveliness_lease_duration:
    sec: 9223372036
    nsec: 854775807
  avoid_ros_namespace_conventions: false"""

JOINT_STATE_MSGDEF = """std_msgs/Header header

string[] name
float64[] position
float64[] velocity
float64[] effort

================================================================================
MSG: std_msgs/Header
builtin_interfaces/Time stamp
string frame_id

================================================================================
MSG: builtin_interfaces/Time
int32 sec
uint32 nanosec
"""


@dataclass
class DriverRecording:
    """What write_driver_bag wrote: the true motion at the header stamps, for comparison."""

    stamps_ns: np.ndarray
    receive_ns: np.ndarray
    q_true: np.ndarray  # URDF order, continuous
    qd_true: np.ndarray


def write_driver_bag(
    bag_dir: pathlib.Path,
    motion: Motion,
    duration_s: float,
    *,
    rate_hz: float = DRIVER_RATE_HZ,
    label: str | None = 'forward',
    seed: int = 0,
    qos_in_mcap: bool = True,
    topic: str = '/joint_states',
) -> DriverRecording:
    """A recording in the style of a real UR driver, written with the mcap libraries (not rosbags).

    qos_in_mcap=False leaves the QoS out of the mcap channel (as mcap_ros2's own Writer does) while
    metadata.yaml lists one: the metadata/storage disagreement that makes rosbags yield nothing.
    """
    import yaml
    from mcap.writer import CompressionType
    from mcap.writer import Writer as McapWriter
    from mcap_ros2._dynamic import serialize_dynamic

    rng = np.random.default_rng(seed)
    bag_dir.mkdir(parents=True)
    file_name = f'{bag_dir.name}_0.mcap'
    stamps_ns = EPOCH_NS + np.round(sample_times_s(duration_s, rate_hz) * 1e9).astype(np.int64)
    # Receive times: stamp plus a bursty transport delay that keeps the order (0.05 - 6 ms).
    receive_ns = stamps_ns + (rng.uniform(0.05, 6.0, len(stamps_ns)) * 1e6).astype(np.int64)
    receive_ns = np.maximum.accumulate(receive_ns)
    q_true, qd_true = motion((stamps_ns - stamps_ns[0]) / 1e9)
    order = [URDF_JOINTS.index(n) for n in DRIVER_JOINTS]
    encode = serialize_dynamic('sensor_msgs/msg/JointState', JOINT_STATE_MSGDEF)['sensor_msgs/msg/JointState']
    rihs = jazzy_typestore().hash_rihs01('sensor_msgs/msg/JointState')
    with open(bag_dir / file_name, 'wb') as stream:
        writer = McapWriter(stream, chunk_size=64 * 1024, compression=CompressionType.ZSTD)
        writer.start(profile='ros2', library='libmcap 1.3.0 (StylePong test writer)')
        schema = writer.register_schema('sensor_msgs/msg/JointState', 'ros2msg', JOINT_STATE_MSGDEF.encode())
        metadata = {'offered_qos_profiles': QOS_YAML, 'topic_type_hash': rihs} if qos_in_mcap else {}
        channel = writer.register_channel(topic, 'cdr', schema, metadata)
        for i, stamp in enumerate(stamps_ns):
            positions = list(q_true[i, order]) + [0.4]
            positions[DRIVER_JOINTS.index('wrist_3_joint')] = float(wrap_to_pi(q_true[i, 5]))
            data = encode(
                {
                    'header': {
                        'stamp': {'sec': int(stamp // 10**9), 'nanosec': int(stamp % 10**9)},
                        'frame_id': 'base_link',
                    },
                    'name': list(DRIVER_JOINTS) + [GRIPPER_JOINT],
                    'position': positions,
                    'velocity': [],
                    'effort': [float(e) for e in rng.normal(0, 2, 7)],
                }
            )
            writer.add_message(
                channel, log_time=int(receive_ns[i]), data=data, publish_time=int(receive_ns[i]), sequence=i
            )
        writer.finish()
    duration_ns = int(receive_ns[-1] - receive_ns[0])
    info = {
        'version': 9,
        'storage_identifier': 'mcap',
        'duration': {'nanoseconds': duration_ns},
        'starting_time': {'nanoseconds_since_epoch': int(receive_ns[0])},
        'message_count': len(stamps_ns),
        'topics_with_message_count': [
            {
                'topic_metadata': {
                    'name': topic,
                    'type': 'sensor_msgs/msg/JointState',
                    'serialization_format': 'cdr',
                    'offered_qos_profiles': yaml.safe_load(QOS_YAML),
                    'type_description_hash': rihs,
                },
                'message_count': len(stamps_ns),
            }
        ],
        'compression_format': '',
        'compression_mode': '',
        'relative_file_paths': [file_name],
        'files': [
            {
                'path': file_name,
                'starting_time': {'nanoseconds_since_epoch': int(receive_ns[0])},
                'duration': {'nanoseconds': duration_ns},
                'message_count': len(stamps_ns),
            }
        ],
        'custom_data': {'label': label} if label is not None else None,
        'ros_distro': 'jazzy',
    }
    (bag_dir / 'metadata.yaml').write_text(yaml.safe_dump({'rosbag2_bagfile_information': info}, sort_keys=False))
    return DriverRecording(stamps_ns=stamps_ns, receive_ns=receive_ns, q_true=q_true, qd_true=qd_true)


def read_with_rosbags(bag: pathlib.Path, joints: Sequence[str] = URDF_JOINTS):
    """(header stamps ns, positions, velocities) in `joints` order, read by rosbags' AnyReader alone.

    The independent reference the tests compare build_dataset's output with.
    """
    from rosbags.highlevel import AnyReader

    stamps, positions, velocities = [], [], []
    with AnyReader([pathlib.Path(bag)], default_typestore=jazzy_typestore()) as reader:
        for connection, _t, raw in reader.messages(reader.connections):
            if connection.msgtype != 'sensor_msgs/msg/JointState':
                continue
            msg = reader.deserialize(raw, connection.msgtype)
            order = [list(msg.name).index(j) for j in joints]
            stamps.append(msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec)
            positions.append(np.asarray(msg.position)[order])
            velocities.append(np.asarray(msg.velocity)[order] if len(msg.velocity) else np.full(len(joints), np.nan))
    return np.array(stamps, dtype=np.int64), np.array(positions), np.array(velocities)


def truncate_file(path: pathlib.Path, keep_fraction: float = 0.6) -> None:
    """Cut a file short, as a process killed while writing leaves it."""
    data = path.read_bytes()
    path.write_bytes(data[: int(len(data) * keep_fraction)])
