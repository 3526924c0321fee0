"""Message definitions and type hashes that a bag stores for each topic (no rclpy imports).

Readers (rosbags AnyReader, mcap-ros2-support, rosbag2) deserialize from the definition stored in the
bag and rosbags checks it against the RIHS01 hash in metadata.yaml, so both must describe exactly the
type on the wire. Standard types come from rosbags' Jazzy type store; any other type (this project's
stylepong_msgs, for one) from the `.msg` files its package installed, found through the ament index.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

from rosbags.interfaces import Nodetype
from rosbags.typesys import Stores, get_types_from_msg, get_typestore


def installed_msg_file(msgtype: str) -> Path | None:
    """`<share>/<pkg>/msg/<Name>.msg` of an installed ROS package, or None."""
    from ament_index_python.packages import PackageNotFoundError, get_package_share_directory

    package, kind, name = msgtype.split('/')
    try:
        path = Path(get_package_share_directory(package)) / kind / f'{name}.msg'
    except PackageNotFoundError:
        return None
    return path if path.is_file() else None


def _referenced_types(fields: list) -> set[str]:
    names = set()
    for _, (node_type, detail) in fields:
        if node_type == Nodetype.NAME:
            names.add(detail)
        elif node_type in (Nodetype.ARRAY, Nodetype.SEQUENCE) and detail[0][0] == Nodetype.NAME:
            names.add(detail[0][1])
    return names


class UnknownMessageType(LookupError):
    """No message definition could be found for a message type."""

    pass


class MessageDefinitions:
    """`definition(msgtype)` -> (ros2msg text with dependencies, 'RIHS01_<hex>')."""

    def __init__(self, find_msg_file: Callable[[str], Path | None] = installed_msg_file):
        self._find_msg_file = find_msg_file
        self._store = get_typestore(Stores.ROS2_JAZZY)
        self._cache: dict[str, tuple[str, str]] = {}

    def definition(self, msgtype: str) -> tuple[str, str]:
        if msgtype not in self._cache:
            if msgtype.count('/') != 2:
                raise UnknownMessageType(f'{msgtype!r} is not a message type name like pkg/msg/Name')
            if msgtype not in self._store.fielddefs:
                self._register_from_files(msgtype)
            msgdef, _ = self._store.generate_msgdef(msgtype, ros_version=2)
            self._cache[msgtype] = (msgdef, self._store.hash_rihs01(msgtype))
        return self._cache[msgtype]

    def _register_from_files(self, msgtype: str) -> None:
        found: dict = {}
        pending = [msgtype]
        while pending:
            name = pending.pop()
            if name in found or name in self._store.fielddefs:
                continue
            path = self._find_msg_file(name)
            if path is None:
                raise UnknownMessageType(f'no definition of {name} (not a standard type, no installed .msg)')
            found.update(get_types_from_msg(path.read_text(), name))
            pending.extend(_referenced_types(found[name][1]))
        self._store.register(found)
