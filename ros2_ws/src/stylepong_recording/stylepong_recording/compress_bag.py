"""`ros2 run stylepong_recording compress_bag <bag_dir>...`: finished mcap bags rewritten with
zstd-compressed chunks, their content unchanged (no ROS imports).

Why: joint states compress well (the joint names and the layout repeat in every message); the shipped
clips take about 2.5 times less room. Each mcap chunk is compressed on its own, the MCAP format's own
compression (what rosbag2's mcap storage writes with its zstd presets), so every mcap reader (rosbags
and this workspace's bag reader, the mcap library, `ros2 bag`, Foxglove) reads the bag as before and
metadata.yaml keeps its form. The recorder itself writes uncompressed chunks: it closes one every flush
period so that a crash loses little, and chunks of a tenth of a second compress poorly; a finished clip
is compressed by this tool (tools/record_demos.sh does it for the clips it records).

The rewrite is recover_bag's (same storage file name, topics, definitions, QoS, log times, custom data),
with compressed chunks; the new bag is read back and compared with the old one, message by message,
before it replaces it. A bag already compressed is left untouched. Exit status: 0 when every bag is
compressed, 1 when one could not be (the reason is printed), 2 for a usage error.
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
from pathlib import Path

from rosbags.rosbag2 import Reader
from rosbags.rosbag2.errors import WriterError

from stylepong_recording.bag_layout import MCAP_STORAGE
from stylepong_recording.bag_metadata import read_metadata
from stylepong_recording.recover_bag import (
    RecoveryError,
    complete_definitions,
    find_storage,
    recover_bag,
    rewrite_bag,
    scan_storage,
)

# rosbags writes zstd; a bag whose chunks use any compression already is left as it is.
CHUNK_COMPRESSION = 'zstd'


class CompressionError(Exception):
    """The bag cannot be compressed; the message says why."""


@dataclasses.dataclass(frozen=True)
class BagContent:
    """What a bag holds, independent of how its storage file is laid out."""

    custom_data: dict
    connections: tuple  # (topic, type, definition, type hash, offered QoS) per connection
    messages: tuple  # (topic, log time in ns, serialized bytes) per message, in log-time order


def bag_content(bag_dir: Path) -> BagContent:
    """Read every connection and message of a bag with rosbags' rosbag2 Reader."""
    with Reader(bag_dir) as reader:
        connections = tuple(
            (c.topic, c.msgtype, c.msgdef.data, c.digest, repr(c.ext.offered_qos_profiles)) for c in reader.connections
        )
        messages = tuple((c.topic, log_time_ns, bytes(raw)) for c, log_time_ns, raw in reader.messages())
        return BagContent(dict(reader.storage.metadata.custom or {}), connections, messages)


@dataclasses.dataclass(frozen=True)
class CompressionReport:
    """What compress_bag did for one bag: sizes of its storage file before and after, in bytes."""

    bag_dir: Path
    outcome: str  # 'compressed' or 'already compressed' (left untouched)
    size_before_bytes: int
    size_after_bytes: int

    def describe(self) -> str:
        if self.outcome != 'compressed':
            return f'{self.bag_dir}: {self.outcome}, left unchanged ({self.size_after_bytes} bytes)'
        return (
            f'{self.bag_dir}: compressed ({CHUNK_COMPRESSION} chunks), {self.size_before_bytes} -> '
            f'{self.size_after_bytes} bytes'
        )


def _same_content_as(original: BagContent, bag_dir: Path):
    """A check for rewrite_bag: the new bag must hold exactly what the old one held."""

    def check(new_bag: Path) -> None:
        if bag_content(new_bag) != original:
            raise CompressionError(f'{bag_dir}: the compressed copy reads back differently; the bag is unchanged')

    return check


def compress_bag(bag_dir: Path) -> CompressionReport:
    """Rewrite the whole mcap bag `bag_dir` with zstd-compressed chunks, its content unchanged."""
    bag_dir = Path(bag_dir)
    try:
        health = recover_bag(bag_dir, check_only=True)
    except RecoveryError as err:
        raise CompressionError(str(err)) from err
    if health.outcome != 'healthy':
        # The first problem is the one that matters (recover_bag lists the missing metadata first).
        first_problem = (health.problems or [health.outcome])[0]
        raise CompressionError(
            f'{bag_dir} is not a whole bag ({first_problem}): make it readable with recover_bag first'
        )
    if health.storage != MCAP_STORAGE:
        raise CompressionError(
            f'{bag_dir} is a {health.storage} bag: only mcap bags have compressed chunks '
            '(convert it with rosbags-convert --dst-storage mcap first)'
        )
    storage, path = find_storage(bag_dir, read_metadata(bag_dir))
    size_before = path.stat().st_size
    scan = scan_storage(storage, path)
    if scan.chunk_compression:
        return CompressionReport(bag_dir, f'already compressed ({scan.chunk_compression})', size_before, size_before)
    original = bag_content(bag_dir)
    scan.chunk_compression = CHUNK_COMPRESSION
    complete_definitions(scan)
    try:
        rewrite_bag(bag_dir, scan, health.custom_data, check=_same_content_as(original, bag_dir))
    except (OSError, WriterError) as err:
        raise CompressionError(f'{bag_dir}: writing the compressed bag failed ({err}); the bag is unchanged') from err
    return CompressionReport(bag_dir, 'compressed', size_before, path.stat().st_size)


def main(argv: list[str] | None = None) -> int:
    """Command line of compress_bag: compress each bag directory given."""
    parser = argparse.ArgumentParser(
        prog='compress_bag',
        description='Rewrite finished mcap bags with zstd-compressed chunks; what they '
        'hold (messages, log times, topics, definitions, QoS, custom data) stays the same.',
    )
    parser.add_argument('bag_dirs', nargs='+', type=Path, metavar='bag_dir', help='rosbag2 bag directory')
    args = parser.parse_args(argv)
    status = 0
    for bag_dir in args.bag_dirs:
        try:
            print(compress_bag(bag_dir).describe())
        except CompressionError as err:
            print(f'compress_bag: error: {err}', file=sys.stderr)
            status = 1
    return status


if __name__ == '__main__':
    sys.exit(main())
