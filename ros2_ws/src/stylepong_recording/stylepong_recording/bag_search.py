"""Finding rosbag2 bags under the paths a user gives: bag directories, single storage files (no rclpy)."""

from __future__ import annotations

import os
import pathlib
from collections.abc import Sequence
from dataclasses import dataclass, field

from stylepong_recording.bag_layout import COMPRESSED_STORAGE_SUFFIXES, METADATA_NAME, STORAGE_SUFFIXES


@dataclass
class BagSearch:
    """Bags found under the paths a user gave, and the paths that held none (with the reason)."""

    bags: list[pathlib.Path] = field(default_factory=list)
    rejected: list[tuple[pathlib.Path, str]] = field(default_factory=list)


def storage_files(directory: pathlib.Path) -> list[pathlib.Path]:
    """The storage files (plain or compressed) directly in `directory`, sorted; none when it is unreadable."""
    try:
        return sorted(
            p
            for p in directory.iterdir()
            if p.is_file() and p.name.endswith(STORAGE_SUFFIXES + COMPRESSED_STORAGE_SUFFIXES)
        )
    except OSError:
        return []


def is_bag_directory(directory: pathlib.Path) -> bool:
    """A rosbag2 bag: metadata.yaml, or (a recording whose metadata was never written) storage files."""
    return (directory / METADATA_NAME).is_file() or bool(storage_files(directory))


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
            if path.name == METADATA_NAME or (path.parent / METADATA_NAME).is_file():
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
                    dirs[:] = []  # a bag's folder holds its files, not further bags
            if not found:
                search.rejected.append((path, 'no rosbag2 bag found in this directory or below it'))
            for bag in found:
                add(bag)
    return search
