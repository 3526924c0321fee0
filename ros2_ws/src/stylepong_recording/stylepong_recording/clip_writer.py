"""Crash-safe writing of one labelled demonstration clip into a rosbag2 bag (no ROS imports).

The bag is written by rosbags (mcap by default, sqlite3 selectable) in the rosbag2 v9 layout:
`<output_dir>/<label>_<time>/` holding the storage file and, once closed, metadata.yaml whose
`custom_data` carries `{label: <label>}`.

Why the extra machinery around rosbags: rosbags keeps mcap messages in a 1 MiB in-memory chunk and
commits sqlite3 only at close, and writes metadata.yaml only at close, so a killed process loses
everything not yet in a finished chunk (tens of seconds of joint states). ClipWriter hands what it
holds to the operating system every `flush_period_s` (mcap: closes the pending chunk, so every chunk on
disk is complete; sqlite3: commits, in WAL mode while recording). A SIGKILL therefore loses at most the
last flush period; the bag then has no metadata.yaml (and an mcap no summary or footer) until
`recover_bag` rebuilds them. Data handed to the OS survives the death of the process; an mcap tail may
not survive a power cut (no fsync per flush: it would cost milliseconds at every flush on a loaded disk).

While a clip is open its directory also holds `recording_in_progress.yaml` (label, storage, start
time): it names a crashed recording for what it is and keeps its label for `recover_bag`. A clean close
removes it.
"""

from __future__ import annotations

import contextlib
import dataclasses
import datetime
import errno
import os
import re
import shutil
import socket
import sqlite3
import time
from collections.abc import Callable, Sequence
from pathlib import Path

import yaml
from rosbags.interfaces import Connection, Qos
from rosbags.rosbag2 import StoragePlugin, Writer
from rosbags.rosbag2.errors import WriterError
from rosbags.rosbag2.storage_mcap import McapWriter
from rosbags.rosbag2.storage_sqlite3 import Sqlite3Writer

from stylepong_recording.bag_layout import (
    CUSTOM_DATA_KEY,
    IN_PROGRESS_NAME,
    LABEL_KEY,
    MCAP_STORAGE,
    ROSBAG2_VERSION,
    STORAGE_IDENTIFIER_KEY,
    STORAGE_SUFFIX,
    STORAGES,
)

DEFAULT_FLUSH_PERIOD_S = 0.1

_LABEL_MAX_LEN = 64
# A label becomes part of a directory name: one path component of portable characters, nothing hidden.
_LABEL_RE = re.compile(r'[A-Za-z0-9][A-Za-z0-9_.-]*')
_TIME_FORMAT = '%Y%m%d_%H%M%S'
# `<label>_<YYYYmmdd>_<HHMMSS>_<milliseconds>`: what bag_dir_name() makes.
_BAG_NAME_RE = re.compile(r'(?P<label>.+)_\d{8}_\d{6}_\d{3}')


class ClipError(Exception):
    """A clip cannot be started or written; the message says why in words a user can act on."""


def label_problem(label: str) -> str | None:
    """Why `label` cannot name a clip, or None when it can."""
    if not label:
        return 'the label is empty'
    if len(label) > _LABEL_MAX_LEN:
        return f'the label is longer than {_LABEL_MAX_LEN} characters'
    if '/' in label or '\\' in label or label in ('.', '..'):
        return f'the label {label!r} contains a path separator or is a relative path'
    if not _LABEL_RE.fullmatch(label):
        return (
            f'the label {label!r} has characters other than letters, digits, "_", "-", "." or starts with "_", "-", "."'
        )
    return None


def bag_dir_name(label: str, when: datetime.datetime) -> str:
    """`<label>_<YYYYmmdd>_<HHMMSS>_<ms>` (local time): sorts by time, unique per label and millisecond."""
    return f'{label}_{when.strftime(_TIME_FORMAT)}_{when.microsecond // 1000:03d}'


def label_from_bag_dir_name(name: str) -> str | None:
    """The label of a directory named by bag_dir_name(), or None when the name has another form."""
    match = _BAG_NAME_RE.fullmatch(name)
    return match.group('label') if match and label_problem(match.group('label')) is None else None


def describe_os_error(err: OSError) -> str:
    """A short reason for an OSError, naming a full disk or an exceeded quota."""
    if err.errno == errno.ENOSPC:
        return f'disk full ({err.strerror})'
    if err.errno == errno.EDQUOT:
        return f'disk quota exceeded ({err.strerror})'
    return err.strerror or str(err)


def recording_process_alive(note: dict) -> bool:
    """Whether the process named in a recording_in_progress.yaml note still runs on this host."""
    pid, host = note.get('pid'), note.get('host')
    if not isinstance(pid, int) or host != socket.gethostname():
        return False
    if Path('/proc/self').exists():
        try:
            # A killed child not yet reaped by its parent is a zombie: dead for our purpose.
            state = Path(f'/proc/{pid}/stat').read_text().rsplit(')', 1)[1].split()[0]
        except (OSError, IndexError):
            return False
        return state not in ('Z', 'X')
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


def free_space_mb(path: Path) -> float:
    """Free disk space (MB) on the file system holding `path`."""
    return shutil.disk_usage(path).free / 1e6


@dataclasses.dataclass(frozen=True)
class TopicSpec:
    """What a bag needs to know about a topic: type, definition for readers, offered QoS."""

    topic: str
    msgtype: str  # e.g. 'sensor_msgs/msg/JointState'
    msgdef: str  # ros2msg text with its dependencies (rosbags' generate_msgdef format)
    rihs01: str  # 'RIHS01_<hex>' type hash
    offered_qos: tuple[Qos, ...] = ()


@dataclasses.dataclass(frozen=True)
class ClipSummary:
    """What a closed clip holds: its bag directory, storage, custom data and message counts per topic."""

    bag_dir: Path
    storage: str
    custom_data: dict[str, str]
    message_counts: dict[str, int]
    first_log_time_ns: int | None
    last_log_time_ns: int | None

    @property
    def message_count(self) -> int:
        return sum(self.message_counts.values())

    @property
    def duration_s(self) -> float:
        if self.first_log_time_ns is None or self.last_log_time_ns is None:
            return 0.0
        return (self.last_log_time_ns - self.first_log_time_ns) * 1e-9

    def describe(self) -> str:
        counts = ', '.join(f'{topic}: {n}' for topic, n in self.message_counts.items()) or 'no topics'
        return f'{self.message_count} messages ({counts}) over {self.duration_s:.2f} s in {self.bag_dir}'


class _FlushingMcapWriter(McapWriter):
    def flush(self) -> None:
        # Closing the pending chunk writes it whole (with its message index): every chunk on disk is
        # complete, so a crash can only cut the file between records of the data section.
        if self.chunk.bio.tell():
            self.close_chunk()
        self.bio.flush()


class _FlushingSqlite3Writer(Sqlite3Writer):
    """Commits at every flush. While recording the database is in WAL mode with synchronous=NORMAL
    (rosbag2's "resilient" preset): a commit appends to the log without waiting for the disk, a killed
    process loses only the open transaction, a power cut no committed one. Closing checkpoints and
    returns to a rollback journal, so a finished bag is one self-contained .db3 file."""

    def __init__(self, path: Path, compression) -> None:
        super().__init__(path, compression)
        self.conn.execute('PRAGMA journal_mode=WAL')
        self.conn.execute('PRAGMA synchronous=NORMAL')

    def flush(self) -> None:
        self.conn.commit()

    def close(self, version: int, metadata: str) -> None:
        super().close(version, metadata)
        with contextlib.closing(sqlite3.connect(self.path)) as conn:
            conn.execute('PRAGMA journal_mode=DELETE')


class _FlushingWriter(Writer):
    STORAGE_PLUGINS = {StoragePlugin.MCAP: _FlushingMcapWriter, StoragePlugin.SQLITE3: _FlushingSqlite3Writer}


def storage_plugin(storage: str) -> StoragePlugin:
    """The rosbags storage plugin of a storage name ('mcap' or 'sqlite3'); ClipError for any other."""
    if storage not in STORAGES:
        raise ClipError(f'unknown storage {storage!r}: use one of {", ".join(STORAGES)}')
    return StoragePlugin.MCAP if storage == MCAP_STORAGE else StoragePlugin.SQLITE3


class ClipWriter:
    """One rosbag2 bag, written through rosbags, flushed to the OS at least every `flush_period_s`.

    Usage: open(), add_topic() for each topic (any time), write() per message, close(). Any failure of
    the file system raises ClipError after closing the file; what was flushed before stays recoverable.
    """

    def __init__(
        self,
        bag_dir: Path,
        storage: str = MCAP_STORAGE,
        custom_data: dict[str, str] | None = None,
        flush_period_s: float = DEFAULT_FLUSH_PERIOD_S,
        monotonic_s: Callable[[], float] = time.monotonic,
    ):
        if not flush_period_s > 0.0:
            raise ClipError(f'flush_period_s must be > 0, got {flush_period_s}')
        self.bag_dir = Path(bag_dir)
        self.storage = storage
        self.custom_data = dict(custom_data or {})
        self.flush_period_s = flush_period_s
        self._monotonic_s = monotonic_s
        self._plugin = storage_plugin(storage)
        self._writer: _FlushingWriter | None = None
        self._connections: dict[str, Connection] = {}
        self._counts: dict[str, int] = {}
        self._first_ns: int | None = None
        self._last_ns: int | None = None
        self._next_flush_s = 0.0
        self._state = 'new'

    @property
    def is_open(self) -> bool:
        return self._state == 'open'

    @property
    def storage_path(self) -> Path:
        return self.bag_dir / f'{self.bag_dir.name}{STORAGE_SUFFIX[self.storage]}'

    def open(self) -> None:
        """Create the bag directory (it must not exist) and its storage file."""
        if self._state != 'new':
            raise ClipError(f'{self.bag_dir}: a ClipWriter opens once')
        if self.bag_dir.exists():
            raise ClipError(f'{self.bag_dir} exists already; a clip never overwrites another')
        try:
            self._writer = _FlushingWriter(self.bag_dir, version=ROSBAG2_VERSION, storage_plugin=self._plugin)
            for key, value in self.custom_data.items():
                self._writer.set_custom_data(key, value)
            self._writer.open()
        except WriterError as err:  # the directory appeared meanwhile: not ours to remove
            self._state = 'failed'
            raise ClipError(f'cannot create the bag {self.bag_dir}: {err}') from err
        except OSError as err:
            self.discard()
            raise ClipError(f'cannot create the bag {self.bag_dir}: {describe_os_error(err)}') from err
        self._state = 'open'
        try:
            self._write_in_progress_note()
            self._writer.storage.flush()
        except OSError as err:
            self.discard()
            raise ClipError(f'cannot create the bag {self.bag_dir}: {describe_os_error(err)}') from err
        self._next_flush_s = self._monotonic_s() + self.flush_period_s

    def add_topic(self, spec: TopicSpec) -> None:
        """Declare a topic (idempotent for the same topic); its schema reaches disk at the next flush."""
        self._require_open()
        if spec.topic in self._connections:
            return
        try:
            self._connections[spec.topic] = self._writer.add_connection(
                spec.topic,
                spec.msgtype,
                msgdef=spec.msgdef,
                rihs01=spec.rihs01,
                offered_qos_profiles=list(spec.offered_qos),
            )
        except OSError as err:
            self._fail(err)
        self._counts[spec.topic] = 0

    def has_topic(self, topic: str) -> bool:
        return topic in self._connections

    def write(self, topic: str, log_time_ns: int, data: bytes | memoryview) -> None:
        """Append one serialized (CDR) message; flushes when the flush period is over."""
        self._require_open()
        connection = self._connections.get(topic)
        if connection is None:
            raise ClipError(f'topic {topic} was not added to {self.bag_dir}')
        try:
            self._writer.write(connection, log_time_ns, data)
        except OSError as err:
            self._fail(err)
        self._counts[topic] += 1
        if self._first_ns is None or log_time_ns < self._first_ns:
            self._first_ns = log_time_ns
        if self._last_ns is None or log_time_ns > self._last_ns:
            self._last_ns = log_time_ns
        self.flush_if_due()

    def flush_if_due(self) -> None:
        if self.is_open and self._monotonic_s() >= self._next_flush_s:
            self.flush()

    def flush(self) -> None:
        """Hand everything written so far to the OS (survives a SIGKILL of this process)."""
        self._require_open()
        try:
            self._writer.storage.flush()
        except OSError as err:
            self._fail(err)
        self._next_flush_s = self._monotonic_s() + self.flush_period_s

    def close(self) -> ClipSummary:
        """Finish the storage file (mcap summary and footer) and write metadata.yaml."""
        self._require_open()
        try:
            self._writer.close()
            self._state = 'closed'
            (self.bag_dir / IN_PROGRESS_NAME).unlink(missing_ok=True)
        except (OSError, WriterError) as err:
            self._fail(err, action='closing')
        return self.summary()

    def abort(self) -> None:
        """Stop writing without finishing the bag: what was flushed stays for `recover_bag`."""
        if self._state == 'open' and self._writer is not None:
            self._state = 'failed'
            try:
                self._writer.abort()
            except Exception:  # noqa: BLE001 - the file may already be gone; nothing left to save
                pass

    def summary(self) -> ClipSummary:
        return ClipSummary(
            self.bag_dir, self.storage, dict(self.custom_data), dict(self._counts), self._first_ns, self._last_ns
        )

    def _require_open(self) -> None:
        if self._state != 'open':
            raise ClipError(f'the bag {self.bag_dir} is not open for writing ({self._state})')

    def _fail(self, err: OSError | WriterError, action: str = 'writing') -> None:
        self.abort()
        reason = describe_os_error(err) if isinstance(err, OSError) else str(err)
        raise ClipError(
            f'{action} {self.bag_dir} failed: {reason}; what was flushed before is kept '
            f'(make it readable with `ros2 run stylepong_recording recover_bag {self.bag_dir}`)'
        ) from err

    def _write_in_progress_note(self) -> None:
        note = {
            CUSTOM_DATA_KEY: self.custom_data,
            STORAGE_IDENTIFIER_KEY: self.storage,
            'started': datetime.datetime.now().astimezone().isoformat(timespec='milliseconds'),
            'host': socket.gethostname(),
            'pid': os.getpid(),
            'note': 'This clip was not closed. If its recorder is gone, make the bag readable with '
            f'`ros2 run stylepong_recording recover_bag {self.bag_dir}`.',
        }
        (self.bag_dir / IN_PROGRESS_NAME).write_text(yaml.safe_dump(note, sort_keys=False))

    def discard(self) -> None:
        """Remove the bag of a clip that failed to start, so it leaves no empty bag behind."""
        self.abort()
        self._state = 'failed'
        if self.bag_dir.is_dir():
            shutil.rmtree(self.bag_dir, ignore_errors=True)


def open_clip(
    output_dir: Path,
    label: str,
    storage: str,
    topics: Sequence[TopicSpec],
    flush_period_s: float = DEFAULT_FLUSH_PERIOD_S,
    min_free_space_mb: float = 0.0,
    now: datetime.datetime | None = None,
) -> ClipWriter:
    """Start a labelled clip `<output_dir>/<label>_<time>` with `topics` declared, or raise ClipError
    with the reason (bad label, unusable output_dir, too little free space, storage failure)."""
    if (problem := label_problem(label)) is not None:
        raise ClipError(problem)
    storage_plugin(storage)
    output_dir = Path(output_dir)
    if output_dir.exists() and not output_dir.is_dir():
        raise ClipError(f'output_dir {output_dir} is not a directory')
    try:
        output_dir.mkdir(parents=True, exist_ok=True)
    except OSError as err:
        raise ClipError(f'output_dir {output_dir} cannot be created: {describe_os_error(err)}') from err
    if not os.access(output_dir, os.W_OK | os.X_OK):
        raise ClipError(f'output_dir {output_dir} is not writable')
    free_mb = free_space_mb(output_dir)
    if free_mb < min_free_space_mb:
        raise ClipError(
            f'disk full: only {free_mb:.1f} MB free in {output_dir} (min_free_space_mb is {min_free_space_mb:g})'
        )
    when = now or datetime.datetime.now()
    clip = ClipWriter(output_dir / bag_dir_name(label, when), storage, {LABEL_KEY: label}, flush_period_s)
    clip.open()
    try:
        for spec in topics:
            clip.add_topic(spec)
        clip.flush()
    except ClipError:
        clip.discard()
        raise
    return clip
