"""A bag's metadata.yaml and the storage files it lists, checked before rosbags opens them (no rclpy).

rosbags' own errors about a missing, empty or cut storage file often do not name the file; these checks
do, and name the way out for a recording that was never closed.
"""

from __future__ import annotations

import pathlib

import yaml

from stylepong_recording.bag_errors import BagError, one_line
from stylepong_recording.bag_layout import (
    CUSTOM_DATA_KEY,
    LABEL_KEY,
    MCAP_SUFFIX,
    METADATA_NAME,
    METADATA_ROOT_KEY,
    RELATIVE_FILE_PATHS_KEY,
    SQLITE3_SUFFIX,
)

MCAP_MAGIC = b'\x89MCAP0\r\n'
SQLITE_MAGIC = b'SQLite format 3\x00'


def read_metadata(bag: pathlib.Path) -> dict | None:
    """The rosbag2_bagfile_information mapping of a bag's metadata.yaml, None when there is none."""
    meta_path = bag / METADATA_NAME
    if not bag.is_dir() or not meta_path.is_file():
        return None
    try:
        document = yaml.safe_load(meta_path.read_text(errors='replace'))
    except (OSError, yaml.YAMLError) as error:
        raise BagError(f'{meta_path}: unreadable metadata.yaml ({one_line(error)})') from None
    info = document.get(METADATA_ROOT_KEY) if isinstance(document, dict) else None
    if not isinstance(info, dict):
        raise BagError(f'{meta_path}: no rosbag2_bagfile_information mapping')
    return info


def metadata_label(info: dict | None) -> str | None:
    """custom_data: label, as written by `ros2 bag record --custom-data label=...` or the recorder."""
    custom = (info or {}).get(CUSTOM_DATA_KEY)
    if isinstance(custom, dict):
        label = custom.get(LABEL_KEY)
        if label is not None and str(label).strip():
            return str(label).strip()
    return None


def check_storage_files(bag: pathlib.Path, info: dict) -> None:
    """Name the exact file when one is missing, empty or cut short (rosbags' own errors often do not)."""
    entries = info.get(RELATIVE_FILE_PATHS_KEY) or []
    if not isinstance(entries, list):
        raise BagError(f'{bag / METADATA_NAME}: relative_file_paths is not a list')
    for entry in entries:
        # rosbags (and rosbag2 since Foxy) resolve storage files by base name inside the bag directory.
        path = bag / pathlib.PurePath(str(entry)).name
        if not path.is_file():
            raise BagError(f'{path}: storage file listed in metadata.yaml is missing')
        size = path.stat().st_size
        if size == 0:
            raise BagError(f'{path}: storage file is empty')
        if path.suffix == MCAP_SUFFIX:
            check_mcap_ends(path)
        elif path.suffix == SQLITE3_SUFFIX:
            with path.open('rb') as stream:
                if stream.read(16) != SQLITE_MAGIC:
                    raise BagError(f'{path}: not an sqlite3 database (bad header)')


def check_mcap_ends(path: pathlib.Path) -> None:
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
        raise BagError(
            f'{path}: truncated mcap file (no footer: the recording was not closed; '
            'ros2 run stylepong_recording recover_bag can rebuild it)'
        )
