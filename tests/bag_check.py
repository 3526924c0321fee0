"""Reading recorded clips back the way their users will, for the recorder's tests.

Two independent readers: rosbags' AnyReader (the bag directory with metadata.yaml) and the mcap library
with mcap-ros2-support's decoder (the .mcap file alone, through its summary and index). Joint states
are identified by their header stamps, so a test can say exactly which published messages a bag holds.
"""
from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import yaml
from rosbags.highlevel import AnyReader
from stylepong_description.robot_model import JOINT_NAMES

from tests import joint_state_bags

JOINT_STATES = '/joint_states'
JOINT_STATE_TYPE = 'sensor_msgs/msg/JointState'
STORE = joint_state_bags.jazzy_typestore()


def stamp_ns(header) -> int:
    return int(header.stamp.sec) * 1_000_000_000 + int(header.stamp.nanosec)


def joint_state_cdr(stamp: int) -> bytes:
    """A serialized JointState whose header stamp (ns) identifies it and whose positions derive from it."""
    return joint_state_bags.joint_state_cdr(STORE, stamp, JOINT_NAMES, np.full(6, stamp * 1e-9), np.zeros(6),
                                            np.zeros(6))


@dataclasses.dataclass
class BagContent:
    custom_data: dict
    stamps: dict[str, list[int]]          # header stamps per topic (ns), in log-time order
    log_times: dict[str, list[int]]
    metadata_counts: dict[str, int]       # message counts metadata.yaml gives per topic


def read_with_rosbags(bag_dir: Path) -> BagContent:
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
            stamps.setdefault(channel.topic, []).append(
                stamp_ns(ros_msg.header) if hasattr(ros_msg, 'header') else -1)
            log_times.setdefault(channel.topic, []).append(message.log_time)
        counts = {summary.channels[cid].topic: n for cid, n in summary.statistics.channel_message_counts.items()}
        metadata = {m.name: m.metadata for m in reader.iter_metadata()}
    return BagContent(metadata, stamps, log_times, counts)


def storage_file(bag_dir: Path, suffix: str) -> Path:
    files = sorted(Path(bag_dir).glob(f'*{suffix}'))
    assert len(files) == 1, f'{bag_dir}: expected one {suffix} file, found {files}'
    return files[0]
