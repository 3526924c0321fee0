"""Read sensor_msgs/JointState recordings out of any rosbag2 bag (no rclpy).

What "any bag" means here, and how each case is handled:
  * bag directories with metadata.yaml (versions 4-9), sqlite3 or mcap storage, split over several
    files, zstd-compressed per file or per message: rosbags' rosbag2 Reader;
  * a directory of .mcap/.db3 files without metadata.yaml, or one such file: read file by file;
  * bags without type definitions (metadata v4-v6 sqlite3): JointState is decoded by the fast CDR
    reader below, which needs no typestore; the ROS 2 Jazzy typestore is the fallback decoder;
  * bags whose other topics carry definitions rosbags cannot parse (service events): only the
    JointState topic's definition is ever parsed, so such bags still open;
  * JointState in another joint order, with extra joints, empty velocity arrays or empty names.
Every way a bag can fail becomes a `BagError` with a one-line reason; per-message failures and
message counts that differ from metadata.yaml are recorded as problems on the result, and the
messages that did decode are kept.

The fast path exists for throughput: rosbags' generic deserializer builds a full message object per
message, which caps a build at the deserializer's rate. `JointStateCdrReader` reads only the stamp,
the names (once per distinct name list) and the position/velocity doubles, and hands any message it
cannot lay out exactly to the generic deserializer.
"""
from __future__ import annotations

import heapq
import math
import os
import pathlib
import struct
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field

import numpy as np
import yaml

from stylepong_fdcc.clip_writer import IN_PROGRESS_NAME

JOINT_STATE_TYPES = ('sensor_msgs/msg/JointState', 'sensor_msgs/JointState')
STORAGE_SUFFIXES = ('.mcap', '.db3')
COMPRESSED_STORAGE_SUFFIXES = ('.mcap.zstd', '.db3.zstd')
MCAP_MAGIC = b'\x89MCAP0\r\n'
SQLITE_MAGIC = b'SQLite format 3\x00'
REASON_MAX_CHARS = 240


class BagError(Exception):
    """A bag (or topic) that cannot be used; the message is a one-line reason for a person."""


def one_line(error: BaseException | str, max_chars: int = REASON_MAX_CHARS) -> str:
    """First line of an error, shortened: rosbags' messages can carry whole schema texts."""
    text = str(error).strip() or type(error).__name__
    if isinstance(error, BaseException) and not isinstance(error, BagError) and type(error).__name__ not in text:
        text = f'{type(error).__name__}: {text}'
    line = text.splitlines()[0] if text else ''
    return line if len(line) <= max_chars else line[:max_chars - 3] + '...'


# ---------------------------------------------------------------------------------------------
# Finding bags


@dataclass
class BagSearch:
    """Bags found under the paths a user gave, and the paths that held none (with the reason)."""
    bags: list[pathlib.Path] = field(default_factory=list)
    rejected: list[tuple[pathlib.Path, str]] = field(default_factory=list)


def _storage_files(directory: pathlib.Path) -> list[pathlib.Path]:
    try:
        return sorted(p for p in directory.iterdir()
                      if p.is_file() and p.name.endswith(STORAGE_SUFFIXES + COMPRESSED_STORAGE_SUFFIXES))
    except OSError:
        return []


def is_bag_directory(directory: pathlib.Path) -> bool:
    """A rosbag2 bag: metadata.yaml, or (a recording whose metadata was never written) storage files."""
    return (directory / 'metadata.yaml').is_file() or bool(_storage_files(directory))


def find_bags(paths: Sequence[str | os.PathLike]) -> BagSearch:
    """Bag directories (or single storage files) in the given paths, searching directories recursively.

    A directory that is itself a bag is not searched further (split files are parts of one bag).
    """
    search = BagSearch()
    seen: set[pathlib.Path] = set()

    def add(bag: pathlib.Path) -> None:
        key = bag.resolve()
        if key not in seen:
            seen.add(key)
            search.bags.append(bag)

    for given in paths:
        path = pathlib.Path(given)
        if not path.exists():
            search.rejected.append((path, 'does not exist'))
        elif path.is_file():
            if path.name == 'metadata.yaml' or (path.parent / 'metadata.yaml').is_file():
                add(path.parent)
            elif path.suffix in STORAGE_SUFFIXES:
                add(path)
            elif path.suffix == '.bag':
                search.rejected.append((path, 'a ROS 1 bag: convert it first (rosbags-convert --src BAG --dst DIR)'))
            else:
                search.rejected.append((path, 'not a rosbag2 bag (no metadata.yaml, not an .mcap or .db3 file)'))
        elif is_bag_directory(path):
            add(path)
        else:
            found = []
            for root, dirs, _files in os.walk(path):
                dirs[:] = sorted(d for d in dirs if not d.startswith('.'))
                here = pathlib.Path(root)
                if here != path and is_bag_directory(here):
                    found.append(here)
                    dirs[:] = []   # a bag's folder holds its files, not further bags
            if not found:
                search.rejected.append((path, 'no rosbag2 bag found in this directory or below it'))
            for bag in found:
                add(bag)
    return search


# ---------------------------------------------------------------------------------------------
# Metadata and storage files


def read_metadata(bag: pathlib.Path) -> dict | None:
    """The rosbag2_bagfile_information mapping of a bag's metadata.yaml, None when there is none."""
    meta_path = bag / 'metadata.yaml'
    if not bag.is_dir() or not meta_path.is_file():
        return None
    try:
        document = yaml.safe_load(meta_path.read_text(errors='replace'))
    except (OSError, yaml.YAMLError) as error:
        raise BagError(f'{meta_path}: unreadable metadata.yaml ({one_line(error)})') from None
    info = document.get('rosbag2_bagfile_information') if isinstance(document, dict) else None
    if not isinstance(info, dict):
        raise BagError(f'{meta_path}: no rosbag2_bagfile_information mapping')
    return info


def metadata_label(info: dict | None) -> str | None:
    """custom_data: label, as written by `ros2 bag record --custom-data label=...` or the recorder."""
    custom = (info or {}).get('custom_data')
    if isinstance(custom, dict):
        label = custom.get('label')
        if label is not None and str(label).strip():
            return str(label).strip()
    return None


def check_storage_files(bag: pathlib.Path, info: dict) -> None:
    """Name the exact file when one is missing, empty or cut short (rosbags' own errors often do not)."""
    entries = info.get('relative_file_paths') or []
    if not isinstance(entries, list):
        raise BagError(f'{bag / "metadata.yaml"}: relative_file_paths is not a list')
    for entry in entries:
        # rosbags (and rosbag2 since Foxy) resolve storage files by base name inside the bag directory.
        path = bag / pathlib.PurePath(str(entry)).name
        if not path.is_file():
            raise BagError(f'{path}: storage file listed in metadata.yaml is missing')
        size = path.stat().st_size
        if size == 0:
            raise BagError(f'{path}: storage file is empty')
        if path.suffix == '.mcap':
            _check_mcap_ends(path)
        elif path.suffix == '.db3':
            with path.open('rb') as stream:
                if stream.read(16) != SQLITE_MAGIC:
                    raise BagError(f'{path}: not an sqlite3 database (bad header)')


def _check_mcap_ends(path: pathlib.Path) -> None:
    """An mcap file starts and ends with the magic; a writer that died never wrote the end."""
    size = path.stat().st_size
    if size == 0:
        raise BagError(f'{path}: storage file is empty')
    with path.open('rb') as stream:
        head = stream.read(8)
        stream.seek(max(0, size - 8))
        tail = stream.read(8)
    if head != MCAP_MAGIC:
        raise BagError(f'{path}: not an mcap file (bad magic)')
    if tail != MCAP_MAGIC or size < 2 * len(MCAP_MAGIC) + 37:
        raise BagError(f'{path}: truncated mcap file (no footer: the recording was not closed; '
                       'ros2 run stylepong_fdcc recover_bag can rebuild it)')


# ---------------------------------------------------------------------------------------------
# Decoding JointState


_U32 = struct.Struct('<I')
_STAMP = struct.Struct('<iI')
NS_PER_S = 1_000_000_000
_DOUBLES: dict[int, struct.Struct] = {}
_CDR_LITTLE_ENDIAN = b'\x00\x01'
# CDR alignment counts from the end of the 4-byte encapsulation header.
_PAYLOAD = 4
# Serializers may pad a message to a multiple of 4 or 8 bytes.
_MAX_TRAILING_PADDING = 7


def _doubles(count: int) -> struct.Struct:
    packer = _DOUBLES.get(count)
    if packer is None:
        packer = _DOUBLES[count] = struct.Struct(f'<{count}d')
    return packer


class CdrLayoutError(ValueError):
    """The bytes are not a little-endian CDR sensor_msgs/JointState laid out as expected."""


def _decode_names(block: memoryview | bytes) -> tuple[str, ...]:
    (count,) = _U32.unpack_from(block, 0)
    names, offset = [], 4
    for _ in range(count):
        offset = (offset + 3) & ~3
        (length,) = _U32.unpack_from(block, offset)
        raw = bytes(block[offset + 4:offset + 4 + length])
        names.append(raw.rstrip(b'\x00').decode('utf-8', errors='replace'))
        offset += 4 + length
    return tuple(names)


@dataclass(frozen=True)
class CdrLayout:
    """Where one message's fields lie (byte offsets from the start of the message)."""
    size: int
    name_id: int
    layout_bytes: tuple[tuple[int, int], ...]   # (start, stop) spans that fix every offset below
    position_offset: int
    position_count: int
    velocity_offset: int
    velocity_count: int


class JointStateCdrReader:
    """Reads stamp, names, positions and velocities straight from CDR bytes.

    `layout` walks one message. `read_batch` walks the first message of a batch and then checks, with
    one numpy comparison, which other messages share its length and every byte that decides a field's
    offset (encapsulation, frame_id length, name block, array lengths): those are read as columns of
    one byte matrix. A driver's messages nearly always share one layout, so the per-message Python
    cost is rosbags' own iteration. The name list is decoded once per distinct name block.
    """

    def __init__(self) -> None:
        self.name_lists: list[tuple[str, ...]] = []
        self._name_ids: dict[bytes, int] = {}
        self._last_block = b''
        self._last_id = -1

    def layout(self, raw: bytes) -> CdrLayout:
        try:
            return self._layout(raw)
        except struct.error as error:
            raise CdrLayoutError(f'message too short ({len(raw)} bytes): {error}') from None

    def _layout(self, raw: bytes) -> CdrLayout:
        if raw[:2] != _CDR_LITTLE_ENDIAN:
            raise CdrLayoutError(f'encapsulation {raw[:2].hex()} is not little-endian CDR')
        size = len(raw) - _PAYLOAD
        (frame_len,) = _U32.unpack_from(raw, _PAYLOAD + 8)
        pos = (12 + frame_len + 3) & ~3
        if pos > size:
            raise CdrLayoutError('frame_id runs past the end of the message')
        start = _PAYLOAD + pos
        if self._last_block and raw.startswith(self._last_block, start):
            pos += len(self._last_block)
            name_id = self._last_id
        else:
            (count,) = _U32.unpack_from(raw, start)
            if count > size // 4:
                raise CdrLayoutError(f'name count {count} cannot fit in {size} bytes')
            pos += 4
            for _ in range(count):
                pos = (pos + 3) & ~3
                (length,) = _U32.unpack_from(raw, _PAYLOAD + pos)
                pos += 4 + length
                if pos > size:
                    raise CdrLayoutError('a joint name runs past the end of the message')
            block = raw[start:_PAYLOAD + pos]
            name_id = self._name_ids.get(block)
            if name_id is None:
                name_id = self._name_ids[block] = len(self.name_lists)
                self.name_lists.append(_decode_names(block))
            self._last_block, self._last_id = block, name_id
        spans = [(0, _PAYLOAD), (_PAYLOAD + 8, _PAYLOAD + 12), (start, _PAYLOAD + pos)]
        arrays = []
        for _ in range(3):   # position, velocity, effort
            pos = (pos + 3) & ~3
            (count,) = _U32.unpack_from(raw, _PAYLOAD + pos)
            spans.append((_PAYLOAD + pos, _PAYLOAD + pos + 4))
            pos += 4
            if count:
                if count > size // 8:
                    raise CdrLayoutError(f'array length {count} cannot fit in {size} bytes')
                pos = (pos + 7) & ~7
            arrays.append((_PAYLOAD + pos, count))
            pos += 8 * count
        if not 0 <= size - pos <= _MAX_TRAILING_PADDING:
            raise CdrLayoutError(f'layout ends at byte {pos + _PAYLOAD} of {len(raw)}: not a standard JointState')
        return CdrLayout(size=len(raw), name_id=name_id, layout_bytes=tuple(spans),
                         position_offset=arrays[0][0], position_count=arrays[0][1],
                         velocity_offset=arrays[1][0], velocity_count=arrays[1][1])

    def read(self, raw: bytes) -> tuple[int, int, tuple, tuple]:
        """(stamp_ns, name_id, positions, velocities) of one message."""
        layout = self.layout(raw)
        sec, nanosec = _STAMP.unpack_from(raw, _PAYLOAD)
        positions = _doubles(layout.position_count).unpack_from(raw, layout.position_offset)
        velocities = _doubles(layout.velocity_count).unpack_from(raw, layout.velocity_offset)
        return sec * NS_PER_S + nanosec, layout.name_id, positions, velocities

    def read_batch(self, raws: Sequence[bytes], template: bytes) -> tuple[CdrLayout, np.ndarray, np.ndarray,
                                                                           np.ndarray, np.ndarray]:
        """Messages laid out like `template`: (layout, row indices, stamps_ns, positions, velocities)."""
        layout = self.layout(template)
        lengths = np.fromiter(map(len, raws), dtype=np.int64, count=len(raws))
        rows = np.flatnonzero(lengths == layout.size)
        matrix = np.frombuffer(b''.join([raws[i] for i in rows]), dtype=np.uint8).reshape(len(rows), layout.size)
        columns = np.concatenate([np.arange(a, b) for a, b in layout.layout_bytes])
        same = (matrix[:, columns] == np.frombuffer(template, dtype=np.uint8)[columns]).all(axis=1)
        rows, matrix = rows[same], matrix[same]
        sec = np.ascontiguousarray(matrix[:, _PAYLOAD:_PAYLOAD + 4]).view('<i4').ravel().astype(np.int64)
        nanosec = np.ascontiguousarray(matrix[:, _PAYLOAD + 4:_PAYLOAD + 8]).view('<u4').ravel().astype(np.int64)

        def doubles(offset: int, count: int) -> np.ndarray:
            return np.ascontiguousarray(matrix[:, offset:offset + 8 * count]).view('<f8').reshape(len(rows), count)
        return (layout, rows, sec * NS_PER_S + nanosec, doubles(layout.position_offset, layout.position_count),
                doubles(layout.velocity_offset, layout.velocity_count))

    def name_id_for(self, names: Sequence[str]) -> int:
        """Register a name list decoded elsewhere (the generic deserializer)."""
        key = b'\xff' + '\x00'.join(names).encode()   # cannot collide with a CDR block (starts with a count)
        name_id = self._name_ids.get(key)
        if name_id is None:
            name_id = self._name_ids[key] = len(self.name_lists)
            self.name_lists.append(tuple(names))
        return name_id


def _is_standard_joint_state(connection, jazzy_store) -> bool:
    """Whether the bag's JointState definition is the one the fast reader assumes.

    rosbag2 stores a RIHS01 hash (Iron and later) and/or the definition text; bags without either
    (Humble sqlite3) carry the standard type, which has not changed across ROS 2 releases.
    """
    digest = getattr(connection, 'digest', '') or ''
    if digest.startswith('RIHS01_'):
        return digest == jazzy_store.hash_rihs01('sensor_msgs/msg/JointState')
    msgdef = getattr(connection, 'msgdef', None)
    data = getattr(msgdef, 'data', '') if msgdef is not None else ''
    if not data:
        return True
    try:
        types = _types_from_definition(connection)
    except Exception:   # noqa: BLE001  an unparsable definition: trust the standard layout, per message checked
        return True
    for name in ('sensor_msgs/msg/JointState', 'std_msgs/msg/Header', 'builtin_interfaces/msg/Time'):
        if name in types and types[name] != jazzy_store.fielddefs.get(name):
            return False
    return True


def _types_from_definition(connection) -> dict:
    from rosbags.interfaces import MessageDefinitionFormat
    from rosbags.typesys import get_types_from_idl, get_types_from_msg
    msgdef = connection.msgdef
    if msgdef.format == MessageDefinitionFormat.MSG:
        return dict(get_types_from_msg(msgdef.data, connection.msgtype))
    if msgdef.format == MessageDefinitionFormat.IDL:
        separator = '=' * 80 + '\n'
        types: dict = {}
        parts = msgdef.data.split(separator)[1:] if msgdef.data.startswith(f'{separator}IDL: ') else [msgdef.data]
        for part in parts:
            idl = part.split('\n', 1)[1] if part.startswith('IDL: ') else part
            types.update(get_types_from_idl(idl))
        return types
    return {}


def _normalise_type_name(msgtype: str) -> str:
    return 'sensor_msgs/msg/JointState' if msgtype in JOINT_STATE_TYPES else msgtype


class GenericJointStateDecoder:
    """rosbags' deserializer for one connection: the bag's own definition, else the Jazzy typestore."""

    def __init__(self, connection, jazzy_store) -> None:
        from rosbags.typesys import Stores, get_typestore
        self.msgtype = _normalise_type_name(connection.msgtype)
        self.error: str | None = None
        try:
            types = _types_from_definition(connection)
        except Exception as error:   # noqa: BLE001
            types = {}
            self.error = f'definition in the bag is unparsable ({one_line(error)})'
        if types:
            self.store = get_typestore(Stores.EMPTY)
            self.store.register(types)
        else:
            self.store = jazzy_store

    def decode(self, raw: bytes) -> tuple[int, int, tuple[str, ...], np.ndarray, np.ndarray]:
        msg = self.store.deserialize_cdr(raw, self.msgtype)
        stamp = msg.header.stamp
        return (int(stamp.sec), int(stamp.nanosec), tuple(msg.name), np.asarray(msg.position, float),
                np.asarray(msg.velocity, float))


# ---------------------------------------------------------------------------------------------
# Reading a bag


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
    problems: list[str] = field(default_factory=list)   # data was lost or may be wrong
    notes: list[str] = field(default_factory=list)      # handled quirks worth knowing

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
        raise BagError(f'a recording still in progress or never closed ({IN_PROGRESS_NAME} is there, metadata.yaml '
                       'is not): let it finish, or rebuild it with ros2 run stylepong_fdcc recover_bag')
    files = [bag] if bag.is_file() else _storage_files(bag)
    for path in files:
        if path.suffix == '.mcap':
            _check_mcap_ends(path)
    if any(f.name.endswith(COMPRESSED_STORAGE_SUFFIXES) for f in files):
        raise BagError(f'{bag}: compressed storage files without metadata.yaml cannot be read '
                       '(the compression mode is only recorded there)')
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
    (name, conns), = joint_topics.items()
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


@dataclass
class _Block:
    """Messages sharing one name list and array lengths, as arrays."""
    name_id: int
    stamp_ns: np.ndarray
    receive_ns: np.ndarray
    position: np.ndarray   # (n, P) in the message's own joint order
    velocity: np.ndarray   # (n, V); V is 0 when the messages carry no velocities


class _Collector:
    """Decodes one connection's messages in batches into `_Block`s."""

    BATCH = 8192
    # Layouts tried per batch before the rest is read message by message (a driver has one).
    LAYOUT_TRIES = 3

    def __init__(self, connection, jazzy_store, fast: bool) -> None:
        self.cdr = JointStateCdrReader()
        self.fast = fast
        self.generic: GenericJointStateDecoder | None = None
        self.connection = connection
        self.jazzy_store = jazzy_store
        self.blocks: list[_Block] = []
        self.yielded = 0
        self.failed = 0
        self.first_failure: str | None = None

    def add_all(self, messages) -> int:
        """Decode (receive_time_ns, raw) pairs; returns how many were yielded (decoded or not).

        A storage that fails part-way raises, but what it gave until then is decoded and counted.
        """
        times: list[int] = []
        raws: list[bytes] = []
        try:
            for timestamp, raw in messages:
                times.append(timestamp)
                raws.append(raw)
                if len(raws) >= self.BATCH:
                    self.yielded += len(raws)
                    self._decode_batch(times, raws)
                    times, raws = [], []
        finally:
            self.yielded += len(raws)
            self._decode_batch(times, raws)
        return self.yielded

    def _decode_batch(self, times: list[int], raws: list[bytes]) -> None:
        if not raws:
            return
        receive = np.asarray(times, dtype=np.int64)
        pending = np.ones(len(raws), dtype=bool)
        slow: dict[tuple[int, int, int], list] = {}

        def decode_slowly(i: int) -> None:
            decoded = self._decode_one(raws[i])
            if decoded is not None:
                stamp_ns, name_id, pos, vel = decoded
                slow.setdefault((name_id, len(pos), len(vel)), []).append((stamp_ns, int(receive[i]), pos, vel))

        for _ in range(self.LAYOUT_TRIES if self.fast else 0):
            if not pending.any():
                break
            first = int(np.argmax(pending))
            try:
                layout, rows, stamps, pos, vel = self.cdr.read_batch(raws, raws[first])
            except CdrLayoutError:
                pending[first] = False
                decode_slowly(first)
                continue
            fresh = pending[rows]
            rows = rows[fresh]
            pending[rows] = False
            self.blocks.append(_Block(name_id=layout.name_id, stamp_ns=stamps[fresh], receive_ns=receive[rows],
                                      position=pos[fresh], velocity=vel[fresh]))
        for i in np.flatnonzero(pending):
            decode_slowly(int(i))
        for (name_id, n_pos, n_vel), items in slow.items():
            self.blocks.append(_Block(
                name_id=name_id, stamp_ns=np.array([x[0] for x in items], dtype=np.int64),
                receive_ns=np.array([x[1] for x in items], dtype=np.int64),
                position=np.array([x[2] for x in items], dtype=float).reshape(len(items), n_pos),
                velocity=np.array([x[3] for x in items], dtype=float).reshape(len(items), n_vel)))

    def _decode_one(self, raw: bytes) -> tuple[int, int, tuple, tuple] | None:
        fast_error = None
        if self.fast:
            try:
                return self.cdr.read(raw)
            except CdrLayoutError as error:
                fast_error = error
        if self.generic is None:
            self.generic = GenericJointStateDecoder(self.connection, self.jazzy_store)
        try:
            sec, nanosec, names, pos, vel = self.generic.decode(raw)
        except Exception as error:   # noqa: BLE001  any decoder failure is one bad message
            self.failed += 1
            if self.first_failure is None:
                reason = one_line(error)
                if self.generic.error:
                    reason += f'; {self.generic.error}'
                elif fast_error is not None:
                    reason += f' (fast reader: {one_line(fast_error)})'
                self.first_failure = reason
            return None
        return sec * NS_PER_S + nanosec, self.cdr.name_id_for(names), tuple(pos.tolist()), tuple(vel.tolist())


def _assemble(collector: _Collector, joints: Sequence[str], assume_order: bool, topic: str,
              problems: list[str], notes: list[str]) -> list[tuple[np.ndarray, ...]]:
    """(stamps, receive times, positions, velocities) per block, columns in `joints` order."""
    n_joints = len(joints)
    parts = []
    unusable: dict[tuple[str, ...], int] = {}
    mismatched = 0
    for block in collector.blocks:
        names = collector.cdr.name_lists[block.name_id]
        count = len(block.stamp_ns)
        if not names:
            if not assume_order:
                raise BagError(f'{topic}: messages have an empty name[]; pass --assume-order to take '
                               f'positions in --joints order ({", ".join(joints)})')
            columns, width = np.arange(n_joints), n_joints
        else:
            if any(j not in names for j in joints):
                unusable[names] = unusable.get(names, 0) + count
                continue
            columns, width = np.array([names.index(j) for j in joints]), len(names)
        if block.position.shape[1] != width:
            mismatched += count
            continue
        velocity = (block.velocity[:, columns] if block.velocity.shape[1] == width
                    else np.full((count, n_joints), np.nan))
        parts.append((block.stamp_ns, block.receive_ns, block.position[:, columns], velocity))
    if mismatched:
        what = 'their name list' if assume_order is False else 'their name list (or --joints)'
        problems.append(f'{topic}: {mismatched} messages whose position array length differs from {what}: dropped')
    if unusable:
        listing = '; '.join(f'{n} messages with joints [{", ".join(names)}]' for names, n in unusable.items())
        if not parts:
            raise BagError(f'{topic}: no message carries all of the joints {", ".join(joints)} ({listing}); '
                           'choose them with --joints')
        notes.append(f'{topic}: ignored {listing} (they lack some of --joints)')
    return parts


def read_joint_states(bag: str | os.PathLike, *, topic: str | None = None,
                      joints: Sequence[str], assume_order: bool = False) -> JointStateRecording:
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
    except Exception as error:   # noqa: BLE001  rosbags raises several types for unreadable bags
        raise BagError(f'cannot open: {one_line(error)}') from None

    chosen_topic = topic
    storage_ids = set()
    collectors: list[_Collector] = []
    for source in sources:
        try:
            source.reader.open()
        except Exception as error:   # noqa: BLE001
            where = '' if source.path == bag else f' {source.path}'
            raise BagError(f'cannot open{where}: {one_line(error)}') from None
        try:
            storage_ids.add(str((info or {}).get('storage_identifier') or source.path.suffix.lstrip('.')))
            chosen_topic, conns = _select_topic(list(source.reader.connections), topic)
            for conn in conns:
                collectors.append(_read_connection(source, conn, chosen_topic, jazzy, problems, notes))
        finally:
            try:
                source.reader.close()
            except Exception:   # noqa: BLE001  closing a half-open reader must not hide the real error
                pass

    parts = [part for c in collectors for part in _assemble(c, joints, assume_order, chosen_topic, problems, notes)]
    stamps, receive, position, velocity = (np.concatenate([p[i] for p in parts]) if parts else np.zeros(0)
                                           for i in range(4))
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
    order = np.argsort(receive, kind='stable')   # several blocks, connections or files: one time line
    return JointStateRecording(
        bag=bag, topic=chosen_topic, joint_names=tuple(joints), header_stamp_ns=stamps[order],
        receive_time_ns=receive[order], position_rad=position[order], velocity_rad_s=velocity[order],
        label=metadata_label(info), storage='+'.join(sorted(storage_ids)), problems=problems, notes=notes)


def _read_connection(source: _Source, conn, topic: str, jazzy, problems: list[str], notes: list[str]) -> _Collector:
    """Decode one connection, checking the yielded count against the one in metadata.yaml."""
    fast = _is_standard_joint_state(conn, jazzy)
    if not fast:
        notes.append(f'{topic}: JointState definition differs from the standard one: generic decoder')
    collector = _Collector(conn, jazzy, fast)
    try:
        collector.add_all((ts, raw) for _c, ts, raw in source.reader.messages([conn]))
    except Exception as error:   # noqa: BLE001  a storage that fails part-way
        problems.append(f'{source.path}: reading {topic} stopped after {collector.yielded} messages: '
                        f'{one_line(error)}')
    expected = int(conn.msgcount)
    if collector.yielded != expected:
        where = 'metadata.yaml' if source.has_metadata else 'the file index'
        message = (f'{source.path}: {topic}: rosbags yielded {collector.yielded} of the {expected} messages '
                   f'listed in {where}')
        if collector.yielded < expected and source.has_metadata:
            recovered = _Collector(conn, jazzy, fast)
            try:
                recovered.add_all(_messages_by_storage(source, topic))
            except Exception as error:   # noqa: BLE001
                message += f' (reading the storage directly failed too: {one_line(error)})'
            if recovered.yielded > collector.yielded:
                collector = recovered
                message += (f'; metadata.yaml and the storage disagree (QoS?): read {recovered.yielded} '
                            'from the storage directly')
        problems.append(message)
    if collector.failed:
        problems.append(f'{source.path}: {topic}: {collector.failed} of {collector.yielded} messages could not '
                        f'be decoded (first: {collector.first_failure})')
    return collector


def median_rate_hz(times_ns: np.ndarray) -> float:
    """Median message rate, for reports."""
    steps = np.diff(times_ns)
    steps = steps[steps > 0]
    return 1e9 / float(np.median(steps)) if len(steps) else math.nan
