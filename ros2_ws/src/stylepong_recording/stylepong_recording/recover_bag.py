"""`ros2 run stylepong_recording recover_bag <bag_dir>`: make a killed recording readable (no ROS imports).

A recorder killed mid-clip leaves a bag directory without metadata.yaml, holding either an mcap file
with no summary, index or footer (possibly ending in a cut record), or an sqlite3 file with a hot
rollback journal. This tool reads every complete record that was written, then re-writes the storage
file through rosbags (same storage, same file name, same topics, message definitions, QoS and log
times) and writes metadata.yaml, with the clip's label in `custom_data` (from the old metadata.yaml,
else from `recording_in_progress.yaml`, else from a `<label>_<time>` directory name).

A bag that is already whole (intact storage, metadata.yaml agreeing with it, nothing in progress) is
left untouched, so running the tool twice, or on a healthy bag, changes nothing. Exit status: 0 when
every bag is readable afterwards, 1 when one could not be recovered (the reason is printed), 2 for a
usage error.
"""

from __future__ import annotations

import argparse
import contextlib
import dataclasses
import shutil
import sqlite3
import struct
import sys
from collections.abc import Callable, Iterator
from pathlib import Path

import yaml
from mcap.exceptions import McapError
from mcap.records import Channel as McapChannel
from mcap.records import Chunk, Footer, Header, Message, Schema
from mcap.stream_reader import StreamReader, breakup_chunk
from rosbags.interfaces import Qos
from rosbags.rosbag2 import CompressionFormat, CompressionMode, Reader, Writer
from rosbags.rosbag2.errors import WriterError
from rosbags.rosbag2.metadata import parse_qos
from rosbags.typesys import Stores, get_types_from_idl, get_types_from_msg, get_typestore

from stylepong_recording.bag_layout import (
    COMPRESSED_STORAGE_SUFFIXES,
    CUSTOM_DATA_KEY,
    IN_PROGRESS_NAME,
    LABEL_KEY,
    MCAP_STORAGE,
    MESSAGE_COUNT_KEY,
    METADATA_NAME,
    METADATA_ROOT_KEY,
    RELATIVE_FILE_PATHS_KEY,
    ROSBAG2_VERSION,
    SQLITE3_STORAGE,
    STORAGE_IDENTIFIER_KEY,
    STORAGE_SUFFIX,
    TOPIC_METADATA_KEY,
    TOPIC_NAME_KEY,
    TOPICS_WITH_MESSAGE_COUNT_KEY,
)
from stylepong_recording.clip_writer import label_from_bag_dir_name, recording_process_alive, storage_plugin

_WORK_DIR_NAME = '.recover_bag_work'
_SQLITE_SIDE_FILES = ('-journal', '-wal', '-shm')


class RecoveryError(Exception):
    """The bag cannot be recovered; the message says why."""


@dataclasses.dataclass
class StoredConnection:
    """A connection (topic) as found in a bag's storage file."""

    id: int
    topic: str
    msgtype: str
    msgdef: str
    msgdef_encoding: str  # 'ros2msg' or 'ros2idl'
    serialization_format: str
    offered_qos: list[Qos]
    digest: str = ''


@dataclasses.dataclass
class StorageScan:
    """What a storage file holds, read as far as its records are whole."""

    storage: str
    path: Path
    connections: dict[int, StoredConnection]
    message_counts: dict[int, int]
    intact: bool
    problems: list[str]
    # mcap only: the compression of its chunks ('' none, 'zstd', 'lz4'); a rewrite keeps them compressed.
    chunk_compression: str = ''

    def counts_by_topic(self) -> dict[str, int]:
        counts: dict[str, int] = {}
        for cid, conn in self.connections.items():
            counts[conn.topic] = counts.get(conn.topic, 0) + self.message_counts.get(cid, 0)
        return counts


@dataclasses.dataclass
class RecoveryReport:
    """What recover_bag found and did for one bag."""

    bag_dir: Path
    storage: str
    outcome: str  # 'healthy' (left untouched), 'recovered', or 'needs recovery' (--check)
    message_counts: dict[str, int]
    custom_data: dict[str, str]
    problems: list[str]

    def describe(self) -> str:
        total = sum(self.message_counts.values())
        counts = ', '.join(f'{t}: {n}' for t, n in self.message_counts.items()) or 'no topics'
        label = self.custom_data.get(LABEL_KEY)
        head = 'healthy, left unchanged' if self.outcome == 'healthy' else self.outcome
        text = f'{self.bag_dir}: {head} ({self.storage}, {total} messages: {counts}'
        text += f', label {label!r})' if label is not None else ', no label)'
        if self.problems:
            text += '\n  found: ' + '\n  found: '.join(self.problems)
        return text


# --- reading what was written -------------------------------------------------------------------------


def _mcap_records(path: Path, problems: list[str], state: dict) -> Iterator[object]:
    """Schema, Channel and Message records of an mcap file, in file order, up to the first cut or
    damaged record. Sets state['intact'] when the file ends with a proper footer and magic."""
    size = path.stat().st_size
    state['intact'] = False
    with path.open('rb') as stream:
        records = StreamReader(stream, emit_chunks=True, record_size_limit=max(size, 1)).records
        good_end = 0
        seen_header = False
        while True:
            try:
                record = next(records)
            except StopIteration:
                state['intact'] = state.get('footer', False)
                return
            except (McapError, struct.error, ValueError, UnicodeDecodeError, EOFError) as err:
                if not seen_header:
                    raise RecoveryError(f'{path} is not an MCAP file ({err})') from err
                if state.get('footer'):
                    problems.append('the mcap footer is damaged')
                elif size > good_end:
                    problems.append(
                        f'the mcap file has no summary or footer and ends in an unfinished '
                        f'record ({size - good_end} bytes after byte {good_end} dropped)'
                    )
                else:
                    problems.append('the mcap file has no summary or footer')
                return
            good_end = stream.tell()
            if isinstance(record, Header):
                seen_header = True
                if record.profile != 'ros2':
                    raise RecoveryError(f'{path} is an MCAP file of profile {record.profile!r}, not ros2')
            elif isinstance(record, Footer):
                state['footer'] = True
            elif isinstance(record, Chunk):
                state['chunk_compression'] = state.get('chunk_compression') or record.compression
                if not record.compression and len(record.data) != record.uncompressed_size:
                    problems.append(f'a damaged chunk ending at byte {good_end} was skipped')
                    continue
                try:
                    yield from breakup_chunk(record, validate_crc=True)
                except (McapError, struct.error, ValueError, UnicodeDecodeError, EOFError) as err:
                    problems.append(f'a damaged chunk ending at byte {good_end} was skipped ({err})')
            elif isinstance(record, (Schema, McapChannel, Message)):
                yield record


def _scan_mcap(path: Path) -> StorageScan:
    problems: list[str] = []
    state: dict = {}
    schemas: dict[int, Schema] = {}
    connections: dict[int, StoredConnection] = {}
    counts: dict[int, int] = {}
    orphans = 0
    for record in _mcap_records(path, problems, state):
        if isinstance(record, Schema):
            schemas.setdefault(record.id, record)
        elif isinstance(record, McapChannel):
            if record.id not in connections:
                schema = schemas.get(record.schema_id)
                if schema is None:
                    problems.append(f'channel {record.topic} has no schema; its messages cannot be kept')
                    continue
                connections[record.id] = StoredConnection(
                    record.id,
                    record.topic,
                    schema.name,
                    schema.data.decode(),
                    schema.encoding,
                    record.message_encoding,
                    parse_qos(record.metadata.get('offered_qos_profiles', '')),
                )
        elif record.channel_id in connections:
            counts[record.channel_id] = counts.get(record.channel_id, 0) + 1
        else:
            orphans += 1
    if orphans:
        problems.append(f'{orphans} messages of unknown channels were dropped')
    return StorageScan(
        MCAP_STORAGE,
        path,
        connections,
        counts,
        state.get('intact', False),
        problems,
        state.get('chunk_compression') or '',
    )


def _mcap_messages(scan: StorageScan) -> Iterator[tuple[int, int, bytes]]:
    for record in _mcap_records(scan.path, [], {}):
        if isinstance(record, Message) and record.channel_id in scan.connections:
            yield record.channel_id, record.log_time, record.data


def _sqlite_connect(path: Path) -> sqlite3.Connection:
    # Read-write on purpose: opening resolves what a killed writer left (replays committed WAL frames,
    # rolls a hot journal back), which makes the database consistent again.
    return sqlite3.connect(f'file:{path}?mode=rw', uri=True)


def scan_storage(storage: str, path: Path) -> StorageScan:
    """What the storage file `path` of kind `storage` ('mcap' or 'sqlite3') holds, read as far as it is whole."""
    return _scan_mcap(path) if storage == MCAP_STORAGE else _scan_sqlite3(path)


def _scan_sqlite3(path: Path) -> StorageScan:
    problems: list[str] = []
    side_files = [s for s in _SQLITE_SIDE_FILES if Path(f'{path}{s}').exists()]
    if side_files:
        problems.append(
            f'the sqlite3 database was not closed ({", ".join(side_files)} left): committed '
            'transactions kept, an unfinished one dropped'
        )
    try:
        with contextlib.closing(_sqlite_connect(path)) as db:
            check = db.execute('PRAGMA quick_check').fetchone()[0]
            if check != 'ok':
                problems.append(f'sqlite3 quick_check: {check}')
            tables = {row[0] for row in db.execute("SELECT name FROM sqlite_master WHERE type='table'")}
            if not {'topics', 'messages'} <= tables:
                raise RecoveryError(f'{path} has no rosbag2 topics/messages tables')
            definitions = {}
            if 'message_definitions' in tables:
                definitions = {
                    t: (enc, text)
                    for t, enc, text in db.execute(
                        'SELECT topic_type, encoding, encoded_message_definition FROM message_definitions'
                    )
                }
            topic_columns = {row[1] for row in db.execute('PRAGMA table_info(topics)')}
            digest_column = 'type_description_hash' if 'type_description_hash' in topic_columns else "''"
            connections = {}
            for cid, topic, msgtype, fmt, qos, digest in db.execute(
                f'SELECT id, name, type, serialization_format, offered_qos_profiles, {digest_column} '
                'FROM topics ORDER BY id'
            ):
                encoding, text = definitions.get(msgtype, ('', ''))
                connections[cid] = StoredConnection(
                    cid, topic, msgtype, text, encoding, fmt, parse_qos(qos or ''), digest or ''
                )
            counts = dict(db.execute('SELECT topic_id, COUNT(*) FROM messages GROUP BY topic_id'))
    except sqlite3.DatabaseError as err:
        raise RecoveryError(f'{path} is not a readable sqlite3 bag ({err})') from err
    return StorageScan(SQLITE3_STORAGE, path, connections, counts, not side_files and not problems, problems)


def _sqlite3_messages(scan: StorageScan) -> Iterator[tuple[int, int, bytes]]:
    with contextlib.closing(_sqlite_connect(scan.path)) as db:
        yield from db.execute('SELECT topic_id, timestamp, data FROM messages ORDER BY id')


# --- deciding and rewriting ---------------------------------------------------------------------------


def _load_yaml(path: Path) -> dict | None:
    try:
        data = yaml.safe_load(path.read_text())
    except (OSError, yaml.YAMLError, UnicodeDecodeError):
        return None
    return data if isinstance(data, dict) else None


def _read_metadata(bag_dir: Path) -> dict | None:
    data = _load_yaml(bag_dir / METADATA_NAME)
    info = data.get(METADATA_ROOT_KEY) if data else None
    return info if isinstance(info, dict) else None


def find_storage(bag_dir: Path, metadata: dict | None) -> tuple[str, Path]:
    """The bag's one storage file and its kind: the file metadata.yaml lists, else the only one there."""
    by_suffix = {suffix: storage for storage, suffix in STORAGE_SUFFIX.items()}
    listed = metadata.get(RELATIVE_FILE_PATHS_KEY) if metadata else None
    if isinstance(listed, list) and len(listed) == 1 and isinstance(listed[0], str):
        path = bag_dir / Path(listed[0]).name
        if path.suffix in by_suffix and path.is_file():
            return by_suffix[path.suffix], path
    files = sorted(p for p in bag_dir.iterdir() if p.is_file() and p.suffix in by_suffix)
    if not files:
        compressed = sorted(p.name for p in bag_dir.iterdir() if p.name.endswith(COMPRESSED_STORAGE_SUFFIXES))
        if compressed:
            raise RecoveryError(f'{bag_dir}: file-compressed bags ({", ".join(compressed)}) are not supported')
        raise RecoveryError(f'{bag_dir} holds no .mcap or .db3 file: nothing to recover')
    if len(files) > 1:
        raise RecoveryError(
            f'{bag_dir} holds several storage files ({", ".join(p.name for p in files)}); '
            'bags split into several files are not supported'
        )
    return by_suffix[files[0].suffix], files[0]


def _custom_data(bag_dir: Path, metadata: dict | None, note: dict | None, problems: list[str]) -> dict[str, str]:
    """The clip's custom data from metadata.yaml, else the recording note, else the directory name."""
    for source in (metadata, note):
        custom = source.get(CUSTOM_DATA_KEY) if source else None
        if isinstance(custom, dict) and custom:
            return {str(k): str(v) for k, v in custom.items()}
    label = label_from_bag_dir_name(bag_dir.name)
    if label is not None:
        problems.append(f'the label {label!r} was taken from the directory name')
        return {LABEL_KEY: label}
    problems.append('no label found (no metadata, no recording note, directory name not <label>_<time>)')
    return {}


def _metadata_matches(bag_dir: Path, metadata: dict | None, scan: StorageScan) -> bool:
    if metadata is None or metadata.get(STORAGE_IDENTIFIER_KEY) != scan.storage:
        return False
    try:
        counts: dict[str, int] = {}
        for entry in metadata[TOPICS_WITH_MESSAGE_COUNT_KEY]:
            name = entry[TOPIC_METADATA_KEY][TOPIC_NAME_KEY]
            counts[name] = counts.get(name, 0) + int(entry[MESSAGE_COUNT_KEY])
        if counts != scan.counts_by_topic():
            return False
        with Reader(bag_dir):
            return True
    except Exception:  # noqa: BLE001 - any failure to read it back means the metadata needs rebuilding
        return False


def _definition_hash(conn: StoredConnection) -> str:
    """RIHS01 of the message definition, computed the way rosbags' AnyReader checks it."""
    try:
        if conn.msgdef_encoding == 'ros2idl':
            sep = '=' * 80 + '\n'
            parts = (
                [p.split('\n', 1)[1] for p in conn.msgdef.split(sep)[1:]]
                if conn.msgdef.startswith(sep + 'IDL: ')
                else [conn.msgdef]
            )
            types = {}
            for idl in parts:
                types.update(get_types_from_idl(idl))
        else:
            types = get_types_from_msg(conn.msgdef, conn.msgtype)
        store = get_typestore(Stores.EMPTY)
        store.register(types)
        return store.hash_rihs01(conn.msgtype)
    except Exception as err:  # noqa: BLE001 - rosbags raises several kinds on a bad definition
        if conn.digest:
            return conn.digest
        raise RecoveryError(f'the message definition of {conn.topic} ({conn.msgtype}) cannot be parsed: {err}') from err


def complete_definitions(scan: StorageScan) -> None:
    """Old sqlite3 bags store no definitions: take them from the Jazzy store when it knows the type."""
    store = None
    for conn in scan.connections.values():
        if not conn.msgdef:
            store = store or get_typestore(Stores.ROS2_JAZZY)
            if conn.msgtype not in store.fielddefs:
                raise RecoveryError(f'{scan.path} stores no definition of {conn.msgtype} and rosbags does not know it')
            conn.msgdef, conn.msgdef_encoding = store.generate_msgdef(conn.msgtype, ros_version=2)[0], 'ros2msg'
        conn.digest = _definition_hash(conn)


def _write_copy(new_bag: Path, scan: StorageScan, custom_data: dict[str, str]) -> None:
    """Everything scanned, written as a fresh bag by rosbags (which also writes its metadata.yaml)."""
    writer = Writer(new_bag, version=ROSBAG2_VERSION, storage_plugin=storage_plugin(scan.storage))
    if scan.chunk_compression:
        # rosbags compresses mcap chunks with zstd only (rosbag2's mcap storage does the same with its
        # zstd presets); readers take the compression from each chunk, metadata.yaml does not record it.
        writer.set_compression(CompressionMode.STORAGE, CompressionFormat.ZSTD)
    for key, value in custom_data.items():
        writer.set_custom_data(key, value)
    messages = _mcap_messages(scan) if scan.storage == MCAP_STORAGE else _sqlite3_messages(scan)
    with writer:
        connections = {
            cid: writer.add_connection(
                conn.topic,
                conn.msgtype,
                msgdef=conn.msgdef,
                rihs01=conn.digest,
                serialization_format=conn.serialization_format,
                offered_qos_profiles=conn.offered_qos,
            )
            for cid, conn in scan.connections.items()
        }
        for cid, log_time_ns, data in messages:
            if cid in connections:
                writer.write(connections[cid], log_time_ns, data)


def rewrite_bag(
    bag_dir: Path, scan: StorageScan, custom_data: dict[str, str], check: Callable[[Path], None] | None = None
) -> None:
    """Write what `scan` found as a new bag beside the old one, `check` it (it raises to keep the old
    bag), then swap it in."""
    work = bag_dir / _WORK_DIR_NAME
    shutil.rmtree(work, ignore_errors=True)
    # rosbags names its storage file after the bag directory: name it like the file it replaces.
    new_bag = work / scan.path.stem
    try:
        work.mkdir()
        _write_copy(new_bag, scan, custom_data)
        if check is not None:
            check(new_bag)
    except BaseException:
        shutil.rmtree(work, ignore_errors=True)  # a full disk must not stay fuller
        raise
    new_storage = new_bag / scan.path.name
    for suffix in _SQLITE_SIDE_FILES:
        Path(f'{scan.path}{suffix}').unlink(missing_ok=True)
    # Storage first, then metadata: an interruption in between leaves a whole storage file that a
    # second run sees as needing only new metadata.
    new_storage.replace(scan.path)
    (new_bag / METADATA_NAME).replace(bag_dir / METADATA_NAME)
    shutil.rmtree(work, ignore_errors=True)
    (bag_dir / IN_PROGRESS_NAME).unlink(missing_ok=True)


def recover_bag(bag_dir: Path, check_only: bool = False, force: bool = False) -> RecoveryReport:
    """Make `bag_dir` a readable rosbag2 bag holding every complete record written to it."""
    bag_dir = Path(bag_dir)
    if not bag_dir.exists():
        raise RecoveryError(f'{bag_dir} does not exist')
    if not bag_dir.is_dir():
        raise RecoveryError(f'{bag_dir} is not a directory (give the bag directory, not a file in it)')
    note = _load_yaml(bag_dir / IN_PROGRESS_NAME)
    if note and not force and recording_process_alive(note):
        # Re-writing the file under a live recorder would make it write into a deleted file.
        raise RecoveryError(
            f'{bag_dir} is still being recorded by process {note["pid"]}: stop the recorder '
            'first (or pass --force if that process is not the recorder)'
        )
    metadata = _read_metadata(bag_dir)
    storage, path = find_storage(bag_dir, metadata)
    scan = scan_storage(storage, path)
    problems = list(scan.problems)
    in_progress = (bag_dir / IN_PROGRESS_NAME).exists()
    healthy = scan.intact and not in_progress and _metadata_matches(bag_dir, metadata, scan)
    if healthy:
        custom = metadata.get(CUSTOM_DATA_KEY) or {}
        return RecoveryReport(bag_dir, storage, 'healthy', scan.counts_by_topic(), dict(custom), problems)
    if in_progress:
        problems.insert(0, f'the recording was not closed ({IN_PROGRESS_NAME})')
    if metadata is None:
        problems.insert(0, f'no readable {METADATA_NAME}')
    elif scan.intact:
        problems.append(f'{METADATA_NAME} disagrees with the storage file')
    custom_data = _custom_data(bag_dir, metadata, note, problems)
    if not check_only:
        complete_definitions(scan)
        try:
            rewrite_bag(bag_dir, scan, custom_data)
        except (OSError, WriterError) as err:
            raise RecoveryError(f'{bag_dir}: writing the recovered bag failed ({err}); the bag is unchanged') from err
    outcome = 'needs recovery' if check_only else 'recovered'
    return RecoveryReport(bag_dir, storage, outcome, scan.counts_by_topic(), custom_data, problems)


def main(argv: list[str] | None = None) -> int:
    """Command line of recover_bag: check or recover each bag directory given."""
    parser = argparse.ArgumentParser(
        prog='recover_bag',
        description='Make rosbag2 bags left by a killed recorder readable: rebuild '
        'metadata.yaml and re-write the mcap (summary, index, footer) or sqlite3 file with every complete '
        'record. Healthy bags are left untouched.',
    )
    parser.add_argument('bag_dirs', nargs='+', type=Path, metavar='bag_dir', help='rosbag2 bag directory')
    parser.add_argument('--check', action='store_true', help='only report what would be done')
    parser.add_argument(
        '--force', action='store_true', help='recover even if the recording note names a process that still runs'
    )
    args = parser.parse_args(argv)
    status = 0
    for bag_dir in args.bag_dirs:
        try:
            report = recover_bag(bag_dir, check_only=args.check, force=args.force)
        except RecoveryError as err:
            print(f'recover_bag: error: {err}', file=sys.stderr)
            status = 1
            continue
        print(report.describe())
    return status


if __name__ == '__main__':
    sys.exit(main())
