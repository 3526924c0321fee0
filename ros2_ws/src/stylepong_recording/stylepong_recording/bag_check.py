"""Reading recorded clips back the way their users will, for the recorder's tests.

Independent readers: rosbags' AnyReader (the bag directory with metadata.yaml); for mcap files the mcap
library with mcap-ros2-support's decoder (the .mcap file alone, through its summary and index); for
sqlite3 files Python's sqlite3 module with a CDR decoder written here (the .db3 file alone: its tables
as rosbag2's sqlite3 storage defines them). Joint states are identified by their header stamps, so a
test can say exactly which published messages a bag holds.
"""

from __future__ import annotations

import dataclasses
import sqlite3
import struct
from pathlib import Path

import numpy as np
import yaml
from rosbags.highlevel import AnyReader

from stylepong_description.robot_model import JOINT_NAMES
from stylepong_recording import joint_state_bags

JOINT_STATES = '/joint_states'
JOINT_STATE_TYPE = 'sensor_msgs/msg/JointState'
WRENCH = '/force_torque_sensor_broadcaster/wrench'
WRENCH_TYPE = 'geometry_msgs/msg/WrenchStamped'
STORE = joint_state_bags.jazzy_typestore()


def stamp_ns(header) -> int:
    """A std_msgs/Header's stamp in nanoseconds."""
    return int(header.stamp.sec) * 1_000_000_000 + int(header.stamp.nanosec)


def joint_state_cdr(stamp: int) -> bytes:
    """A serialized JointState whose header stamp (ns) identifies it and whose positions derive from it."""
    return joint_state_bags.joint_state_cdr(
        STORE, stamp, JOINT_NAMES, np.full(6, stamp * 1e-9), np.zeros(6), np.zeros(6)
    )


@dataclasses.dataclass
class BagContent:
    """What a bag holds, read back through rosbags: its label data and every message's stamps and values."""

    custom_data: dict
    stamps: dict[str, list[int]]  # header stamps per topic (ns), in log-time order
    log_times: dict[str, list[int]]
    metadata_counts: dict[str, int]  # message counts metadata.yaml gives per topic


def read_with_rosbags(bag_dir: Path) -> BagContent:
    """Read a whole bag with rosbags' AnyReader, the reference for what the recorder wrote."""
    with AnyReader([Path(bag_dir)]) as reader:
        stamps: dict[str, list[int]] = {c.topic: [] for c in reader.connections}
        log_times: dict[str, list[int]] = {c.topic: [] for c in reader.connections}
        for connection, log_time, raw in reader.messages():
            msg = reader.deserialize(raw, connection.msgtype)
            stamps[connection.topic].append(stamp_ns(msg.header) if hasattr(msg, 'header') else -1)
            log_times[connection.topic].append(log_time)
        counts = {c.topic: c.msgcount for c in reader.connections}
        custom = dict(reader.readers[0].storage.metadata.custom or {})
    # What rosbag2 itself reads: metadata.yaml's custom_data.
    info = yaml.safe_load((Path(bag_dir) / 'metadata.yaml').read_text())['rosbag2_bagfile_information']
    assert info['version'] == 9 and info.get('custom_data') == (custom or None), info
    return BagContent(custom, stamps, log_times, counts)


def read_with_mcap_ros2(mcap_path: Path) -> BagContent:
    """Through the mcap library's indexed reader (it needs a valid summary and footer)."""
    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory

    stamps: dict[str, list[int]] = {}
    log_times: dict[str, list[int]] = {}
    with open(mcap_path, 'rb') as stream:
        reader = make_reader(stream, decoder_factories=[DecoderFactory()])
        summary = reader.get_summary()
        assert summary is not None and summary.statistics is not None, 'mcap file without summary'
        for _, channel, message, ros_msg in reader.iter_decoded_messages():
            stamps.setdefault(channel.topic, []).append(stamp_ns(ros_msg.header) if hasattr(ros_msg, 'header') else -1)
            log_times.setdefault(channel.topic, []).append(message.log_time)
        counts = {summary.channels[cid].topic: n for cid, n in summary.statistics.channel_message_counts.items()}
        metadata = {m.name: m.metadata for m in reader.iter_metadata()}
    return BagContent(metadata, stamps, log_times, counts)


def storage_file(bag_dir: Path, suffix: str) -> Path:
    """The one storage file of a bag with this suffix."""
    files = sorted(Path(bag_dir).glob(f'*{suffix}'))
    assert len(files) == 1, f'{bag_dir}: expected one {suffix} file, found {files}'
    return files[0]


# --- sqlite3 without rosbags ------------------------------------------------------------------------------
class CdrReader:
    """Little-endian plain CDR (XCDR1, what rmw_fastrtps and rosbag2 write) after its 4-byte encapsulation
    header; primitives are aligned to their size, counted from the end of that header."""

    def __init__(self, data: bytes):
        assert data[:2] == b'\x00\x01', f'not little-endian CDR: encapsulation {data[:2].hex()}'
        self.data, self.offset = data, 4

    def _read(self, fmt: str, size: int):
        self.offset += (-(self.offset - 4)) % size
        value = struct.unpack_from('<' + fmt, self.data, self.offset)[0]
        self.offset += size
        return value

    def int32(self) -> int:
        return self._read('i', 4)

    def uint32(self) -> int:
        return self._read('I', 4)

    def float64(self) -> float:
        return self._read('d', 8)

    def string(self) -> str:
        length = self.uint32()  # including the terminating NUL
        raw = self.data[self.offset : self.offset + length]
        self.offset += length
        assert raw.endswith(b'\x00'), 'CDR string without its NUL'
        return raw[:-1].decode()

    def header(self) -> tuple[int, str]:
        """std_msgs/Header: (stamp ns, frame_id)."""
        sec, nanosec = self.int32(), self.uint32()
        return sec * 1_000_000_000 + nanosec, self.string()


@dataclasses.dataclass
class JointStateCdr:
    """A JointState decoded field by field from its CDR bytes."""

    stamp_ns: int
    frame_id: str
    name: list[str]
    position: list[float]
    velocity: list[float]
    effort: list[float]


def decode_joint_state(data: bytes) -> JointStateCdr:
    """sensor_msgs/msg/JointState from its CDR bytes; every byte must be accounted for."""
    cdr = CdrReader(data)
    stamp, frame = cdr.header()
    names = [cdr.string() for _ in range(cdr.uint32())]
    arrays = [[cdr.float64() for _ in range(cdr.uint32())] for _ in range(3)]
    assert len(data) - cdr.offset < 4, f'{len(data) - cdr.offset} bytes left after a JointState'
    return JointStateCdr(stamp, frame, names, *arrays)


def _starts_with_header(definition: str) -> bool:
    fields = [line.split('#')[0].split() for line in definition.splitlines()]
    fields = [f for f in fields if f]
    return bool(fields) and fields[0][0] in ('std_msgs/Header', 'Header', 'std_msgs/msg/Header')


def read_with_sqlite3(db3_path: Path) -> tuple[BagContent, list[JointStateCdr]]:
    """The .db3 file through Python's sqlite3 alone (read-only); JointStates decoded by decode_joint_state.

    Returns the bag's content (custom_data and counts from the metadata table rosbag2 keeps in the file,
    header stamps of every message type that starts with a Header) and the decoded joint states.
    """
    connection = sqlite3.connect(f'file:{Path(db3_path)}?mode=ro', uri=True)
    try:
        topics = {
            tid: (name, msgtype)
            for tid, name, msgtype, encoding in connection.execute(
                'SELECT id, name, type, serialization_format FROM topics'
            )
            if encoding == 'cdr' or _fail(f'{name}: serialization {encoding}')
        }
        definitions = dict(connection.execute('SELECT topic_type, encoded_message_definition FROM message_definitions'))
        stamps: dict[str, list[int]] = {name: [] for name, _ in topics.values()}
        log_times: dict[str, list[int]] = {name: [] for name, _ in topics.values()}
        joint_states: list[JointStateCdr] = []
        for topic_id, log_time, data in connection.execute(
            'SELECT topic_id, timestamp, data FROM messages ORDER BY timestamp, id'
        ):
            name, msgtype = topics[topic_id]
            if msgtype == JOINT_STATE_TYPE:
                joint_states.append(decode_joint_state(bytes(data)))
                stamps[name].append(joint_states[-1].stamp_ns)
            elif _starts_with_header(definitions.get(msgtype, '')):
                stamps[name].append(CdrReader(bytes(data)).header()[0])
            else:
                stamps[name].append(-1)
            log_times[name].append(log_time)
        rows = connection.execute('SELECT metadata FROM metadata ORDER BY id DESC LIMIT 1').fetchall()
    finally:
        connection.close()
    metadata = yaml.safe_load(rows[0][0]) if rows else {}
    counts = {t['topic_metadata']['name']: t['message_count'] for t in metadata.get('topics_with_message_count', [])}
    return BagContent(dict(metadata.get('custom_data') or {}), stamps, log_times, counts), joint_states


def _fail(message: str):
    raise AssertionError(message)
