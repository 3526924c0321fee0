"""Read sensor_msgs/JointState recordings out of any rosbag2 bag (no rclpy).

What "any bag" means here, and how each case is handled:
  * bag directories with metadata.yaml (versions 4-9), sqlite3 or mcap storage, split over several
    files, zstd-compressed per file or per message: rosbags' rosbag2 Reader;
  * a directory of .mcap/.db3 files without metadata.yaml, or one such file: read file by file;
  * bags without type definitions (metadata v4-v6 sqlite3): JointState is decoded by the fast CDR
    reader (joint_state_cdr), which needs no typestore; the ROS 2 Jazzy typestore is the fallback decoder;
  * bags whose other topics carry definitions rosbags cannot parse (service events): only the
    JointState topic's definition is ever parsed, so such bags still open;
  * JointState in another joint order, with extra joints, empty velocity arrays or empty names.
Every way a bag can fail becomes a `BagError` with a one-line reason; per-message failures and
message counts that differ from metadata.yaml are recorded as problems on the result, and the
messages that did decode are kept.

The pieces: finding bags (bag_search), metadata.yaml and storage-file checks (bag_metadata), the fast
CDR reader (joint_state_cdr) and decoding with its fallbacks (joint_state_decoding); this module opens
a bag, picks its JointState topic and assembles one time line in the requested joint order.
"""

from __future__ import annotations

import heapq
import math
import os
import pathlib
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field

import numpy as np

from stylepong_recording.bag_errors import BagError, one_line
from stylepong_recording.bag_layout import (
    COMPRESSED_STORAGE_SUFFIXES,
    IN_PROGRESS_NAME,
    MCAP_SUFFIX,
    METADATA_NAME,
    STORAGE_IDENTIFIER_KEY,
)
from stylepong_recording.bag_metadata import check_mcap_ends, check_storage_files, metadata_label, read_metadata
from stylepong_recording.bag_search import storage_files
from stylepong_recording.joint_state_decoding import JOINT_STATE_TYPES, JointStateCollector, is_standard_joint_state


@dataclass
class JointStateRecording:
    """One bag's JointState messages, columns in the requested joint order.

    velocity_rad_s is NaN where a message carried no velocity for that joint.
    """

    bag: pathlib.Path
    topic: str
    joint_names: tuple[str, ...]
    header_stamp_ns: np.ndarray
    receive_time_ns: np.ndarray
    position_rad: np.ndarray
    velocity_rad_s: np.ndarray
    label: str | None = None
    storage: str = ''
    problems: list[str] = field(default_factory=list)  # data was lost or may be wrong
    notes: list[str] = field(default_factory=list)  # handled quirks worth knowing

    @property
    def message_count(self) -> int:
        return len(self.header_stamp_ns)


@dataclass
class _Source:
    """A rosbags Reader over a whole bag directory or over one storage file."""

    reader: object
    path: pathlib.Path
    has_metadata: bool


def _open_sources(bag: pathlib.Path, info: dict | None) -> list[_Source]:
    from rosbags.rosbag2 import Reader

    if info is not None:
        return [_Source(Reader(bag), bag, True)]
    if bag.is_dir() and (bag / IN_PROGRESS_NAME).is_file():
        raise BagError(
            f'a recording still in progress or never closed ({IN_PROGRESS_NAME} is there, {METADATA_NAME} '
            'is not): let it finish, or rebuild it with ros2 run stylepong_recording recover_bag'
        )
    files = [bag] if bag.is_file() else storage_files(bag)
    for path in files:
        if path.suffix == MCAP_SUFFIX:
            check_mcap_ends(path)
    if any(f.name.endswith(COMPRESSED_STORAGE_SUFFIXES) for f in files):
        raise BagError(
            f'{bag}: compressed storage files without metadata.yaml cannot be read '
            '(the compression mode is only recorded there)'
        )
    return [_Source(Reader(f), f, False) for f in files]


def _select_topic(connections: list, topic: str | None) -> tuple[str, list]:
    joint_topics: dict[str, list] = {}
    for conn in connections:
        if conn.msgtype in JOINT_STATE_TYPES:
            joint_topics.setdefault(conn.topic, []).append(conn)
    if topic is not None:
        matching = [c for c in connections if c.topic == topic]
        if not matching:
            others = ', '.join(sorted(joint_topics)) or 'none'
            raise BagError(f'no topic {topic} (JointState topics here: {others})')
        wrong = {c.msgtype for c in matching if c.msgtype not in JOINT_STATE_TYPES}
        if wrong:
            raise BagError(f'topic {topic} is {", ".join(sorted(wrong))}, not sensor_msgs/msg/JointState')
        return topic, matching
    if not joint_topics:
        names = sorted({c.topic for c in connections})
        listing = ', '.join(names[:6]) + (f', ... ({len(names)} topics)' if len(names) > 6 else '')
        raise BagError(f'no sensor_msgs/msg/JointState topic (topics: {listing or "none"})')
    if len(joint_topics) > 1:
        listing = ', '.join(f'{t} ({sum(c.msgcount for c in cs)} msgs)' for t, cs in sorted(joint_topics.items()))
        raise BagError(f'several JointState topics: {listing}; choose one with --topic')
    ((name, conns),) = joint_topics.items()
    return name, conns


def _messages_by_storage(source: _Source, topic: str) -> Iterator[tuple[int, bytes]]:
    """Messages of `topic` straight from the storage files, matched by topic name only.

    rosbags pairs metadata.yaml topics with storage topics by name, type AND QoS, and silently yields
    nothing when a hand-edited metadata.yaml disagrees with the storage; this reads past that.
    """
    directory = source.reader.storage
    decompress = None
    if getattr(directory.metadata, 'compression_mode', None) == 'message':
        from rosbags.rosbag2.reader import zstd

        decompress = zstd.decompress
    streams = []
    for storage in directory.storages:
        conns = [c for c in storage.connections if c.topic == topic]
        if conns:
            streams.append(((ts, raw) for _c, ts, raw in storage.messages(conns)))
    for timestamp, raw in heapq.merge(*streams, key=lambda m: m[0]):
        yield timestamp, (decompress(raw) if decompress else raw)


def joint_name_prefix(names: Sequence[str], joints: Sequence[str]) -> str | None:
    """'' when names hold every joint; else the one prefix that names them all (a UR driver started
    with tf_prefix 'ur5_' publishes 'ur5_shoulder_pan_joint', ...); None when no prefix, or more than one,
    does."""
    if all(j in names for j in joints):
        return ''
    first = joints[0]
    candidates = {n[: -len(first)] for n in names if n.endswith(first) and len(n) > len(first)}
    fitting = [p for p in candidates if all(p + j in names for j in joints)]
    return fitting[0] if len(fitting) == 1 else None


def _assemble(
    collector: JointStateCollector,
    joints: Sequence[str],
    assume_order: bool,
    topic: str,
    problems: list[str],
    notes: list[str],
) -> list[tuple[np.ndarray, ...]]:
    """(stamps, receive times, positions, velocities) per block, columns in `joints` order."""
    n_joints = len(joints)
    parts = []
    unusable: dict[tuple[str, ...], int] = {}
    prefixes: set[str] = set()
    mismatched = 0
    for block in collector.blocks:
        names = collector.cdr.name_lists[block.name_id]
        count = len(block.stamp_ns)
        if not names:
            if not assume_order:
                raise BagError(
                    f'{topic}: messages have an empty name[]; pass --assume-order to take '
                    f'positions in --joints order ({", ".join(joints)})'
                )
            columns, width = np.arange(n_joints), n_joints
        else:
            prefix = joint_name_prefix(names, joints)
            if prefix is None:
                unusable[names] = unusable.get(names, 0) + count
                continue
            if prefix and prefix not in prefixes:
                prefixes.add(prefix)
                notes.append(f"{topic}: joints named with the prefix {prefix!r} (a driver's tf_prefix)")
            columns, width = np.array([names.index(prefix + j) for j in joints]), len(names)
        if block.position.shape[1] != width:
            mismatched += count
            continue
        velocity = (
            block.velocity[:, columns] if block.velocity.shape[1] == width else np.full((count, n_joints), np.nan)
        )
        parts.append((block.stamp_ns, block.receive_ns, block.position[:, columns], velocity))
    if mismatched:
        what = 'their name list' if assume_order is False else 'their name list (or --joints)'
        problems.append(f'{topic}: {mismatched} messages whose position array length differs from {what}: dropped')
    if unusable:
        listing = '; '.join(f'{n} messages with joints [{", ".join(names)}]' for names, n in unusable.items())
        if not parts:
            raise BagError(
                f'{topic}: no message carries all of the joints {", ".join(joints)} ({listing}); '
                'choose them with --joints'
            )
        notes.append(f'{topic}: ignored {listing} (they lack some of --joints)')
    return parts


def read_joint_states(
    bag: str | os.PathLike, *, topic: str | None = None, joints: Sequence[str], assume_order: bool = False
) -> JointStateRecording:
    """All JointState messages of one bag's JointState topic, columns in `joints` order.

    Raises BagError (one-line reason) when the bag cannot be used at all.
    """
    from rosbags.typesys import Stores, get_typestore

    bag = pathlib.Path(bag)
    info = read_metadata(bag)
    if info is not None:
        check_storage_files(bag, info)
    jazzy = get_typestore(Stores.ROS2_JAZZY)
    problems: list[str] = []
    notes: list[str] = []
    if info is None:
        notes.append('no metadata.yaml: read the storage file(s) directly; counts from their own index')
    try:
        sources = _open_sources(bag, info)
    except BagError:
        raise
    except Exception as error:  # noqa: BLE001  rosbags raises several types for unreadable bags
        raise BagError(f'cannot open: {one_line(error)}') from None

    chosen_topic = topic
    storage_ids = set()
    collectors: list[JointStateCollector] = []
    for source in sources:
        try:
            source.reader.open()
        except Exception as error:  # noqa: BLE001
            where = '' if source.path == bag else f' {source.path}'
            raise BagError(f'cannot open{where}: {one_line(error)}') from None
        try:
            storage_ids.add(str((info or {}).get(STORAGE_IDENTIFIER_KEY) or source.path.suffix.lstrip('.')))
            chosen_topic, conns = _select_topic(list(source.reader.connections), topic)
            for conn in conns:
                collectors.append(_read_connection(source, conn, chosen_topic, jazzy, problems, notes))
        finally:
            try:
                source.reader.close()
            except Exception:  # noqa: BLE001  closing a half-open reader must not hide the real error
                pass

    parts = [part for c in collectors for part in _assemble(c, joints, assume_order, chosen_topic, problems, notes)]
    stamps, receive, position, velocity = (
        np.concatenate([p[i] for p in parts]) if parts else np.zeros(0) for i in range(4)
    )
    if parts:
        finite = np.isfinite(position).all(axis=1)
        if not finite.all():
            problems.append(f'{chosen_topic}: {int((~finite).sum())} messages with NaN or infinite positions: dropped')
            stamps, receive, position, velocity = stamps[finite], receive[finite], position[finite], velocity[finite]
    if not len(stamps):
        if not any(c.yielded for c in collectors) and not problems:
            raise BagError(f'{chosen_topic}: no messages recorded on it')
        lost = f' ({"; ".join(problems)})' if problems else ''
        raise BagError(f'{chosen_topic}: no usable JointState message{lost}')
    order = np.argsort(receive, kind='stable')  # several blocks, connections or files: one time line
    return JointStateRecording(
        bag=bag,
        topic=chosen_topic,
        joint_names=tuple(joints),
        header_stamp_ns=stamps[order],
        receive_time_ns=receive[order],
        position_rad=position[order],
        velocity_rad_s=velocity[order],
        label=metadata_label(info),
        storage='+'.join(sorted(storage_ids)),
        problems=problems,
        notes=notes,
    )


def _read_connection(
    source: _Source, conn, topic: str, jazzy, problems: list[str], notes: list[str]
) -> JointStateCollector:
    """Decode one connection, checking the yielded count against the one in metadata.yaml."""
    fast = is_standard_joint_state(conn, jazzy)
    if not fast:
        notes.append(f'{topic}: JointState definition differs from the standard one: generic decoder')
    collector = JointStateCollector(conn, jazzy, fast)
    try:
        collector.add_all((ts, raw) for _c, ts, raw in source.reader.messages([conn]))
    except Exception as error:  # noqa: BLE001  a storage that fails part-way
        problems.append(f'{source.path}: reading {topic} stopped after {collector.yielded} messages: {one_line(error)}')
    expected = int(conn.msgcount)
    if collector.yielded != expected:
        where = 'metadata.yaml' if source.has_metadata else 'the file index'
        message = (
            f'{source.path}: {topic}: rosbags yielded {collector.yielded} of the {expected} messages listed in {where}'
        )
        if collector.yielded < expected and source.has_metadata:
            recovered = JointStateCollector(conn, jazzy, fast)
            try:
                recovered.add_all(_messages_by_storage(source, topic))
            except Exception as error:  # noqa: BLE001
                message += f' (reading the storage directly failed too: {one_line(error)})'
            if recovered.yielded > collector.yielded:
                collector = recovered
                message += (
                    f'; metadata.yaml and the storage disagree (QoS?): read {recovered.yielded} '
                    'from the storage directly'
                )
        problems.append(message)
    if collector.failed:
        problems.append(
            f'{source.path}: {topic}: {collector.failed} of {collector.yielded} messages could not '
            f'be decoded (first: {collector.first_failure})'
        )
    return collector


def median_rate_hz(times_ns: np.ndarray) -> float:
    """Median message rate, for reports."""
    steps = np.diff(times_ns)
    steps = steps[steps > 0]
    return 1e9 / float(np.median(steps)) if len(steps) else math.nan
