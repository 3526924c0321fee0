"""The numbers drag_teach needs from a serialized JointState or WrenchStamped, read straight from the bytes.

drag_teach subscribes to both at 500 Hz with `raw=True`: building the Python message objects cost more
than the controller itself (about 27 us for a JointState and 40 us for a WrenchStamped, against 70 us for
a whole control cycle; benchmarks/40_drag_teach.py), and all it needs is the joint names, the positions
and six doubles. The layout is plain CDR, little endian as ROS 2 middlewares write it on these machines:
a 4-byte encapsulation header, then the fields in order, each aligned to its size from the start of the
body (8 for doubles). Anything else (big endian, a truncated buffer) is handed to rclpy's deserialiser,
so the readers below only ever take a shortcut, never a different answer.
"""
from __future__ import annotations

import struct

import numpy as np
from geometry_msgs.msg import WrenchStamped
from rclpy.serialization import deserialize_message
from sensor_msgs.msg import JointState

_HEADER_BYTES = 4            # encapsulation: representation id (2 bytes), options (2 bytes)
_LITTLE_ENDIAN_CDR = (0x00, 0x01)
_STAMP_BYTES = 8             # builtin_interfaces/Time: int32 sec, uint32 nanosec
_UINT32 = struct.Struct('<I')


def _aligned(offset: int, size: int) -> int:
    """`offset` (from the start of the body) rounded up to a multiple of `size`."""
    return (offset + size - 1) & ~(size - 1)


def _is_little_endian_cdr(raw: bytes) -> bool:
    return len(raw) >= _HEADER_BYTES and (raw[0], raw[1]) == _LITTLE_ENDIAN_CDR


def _after_header_body_offset(raw: bytes) -> int:
    """Body offset just past a std_msgs/Header (stamp, then frame_id as length-prefixed string)."""
    frame_id_bytes = _UINT32.unpack_from(raw, _HEADER_BYTES + _STAMP_BYTES)[0]
    return _STAMP_BYTES + 4 + frame_id_bytes


def wrench_from_cdr(raw: bytes) -> np.ndarray:
    """(force x, y, z, torque x, y, z) of a serialized geometry_msgs/WrenchStamped."""
    if _is_little_endian_cdr(raw):
        start = _HEADER_BYTES + _aligned(_after_header_body_offset(raw), 8)
        if start + 48 <= len(raw):
            return np.frombuffer(raw, '<f8', 6, start).astype(float)
    msg = deserialize_message(raw, WrenchStamped)
    f, t = msg.wrench.force, msg.wrench.torque
    return np.array([f.x, f.y, f.z, t.x, t.y, t.z])


class JointStateReader:
    """Joint positions of serialized sensor_msgs/JointState messages in a fixed joint order.

    The names of a publisher's messages rarely change, so the name block's bytes are kept with the
    joint indices they gave: a message whose name block is the same byte for byte has the same names.
    """

    def __init__(self, joint_names: tuple[str, ...]):
        self.joint_names = tuple(joint_names)
        self._name_block = b''
        self._indices: np.ndarray | None = None
        self._name_count = 0

    def positions(self, raw: bytes) -> tuple[np.ndarray | None, int, int]:
        """(positions in `joint_names` order or None when a joint is missing, name count, position count)."""
        if _is_little_endian_cdr(raw):
            try:
                return self._positions_from_cdr(raw)
            except (struct.error, ValueError, IndexError):
                pass   # not what the layout promised: let rclpy read it
        msg = deserialize_message(raw, JointState)
        return self._select(tuple(msg.name), np.asarray(msg.position, dtype=float), len(msg.position))

    def _positions_from_cdr(self, raw: bytes) -> tuple[np.ndarray | None, int, int]:
        names_start = _HEADER_BYTES + _aligned(_after_header_body_offset(raw), 4)
        block_end = names_start + len(self._name_block)
        if self._name_block and raw[names_start:block_end] == self._name_block:
            names_end, indices, name_count = block_end, self._indices, self._name_count
        else:
            names, names_end = _read_strings(raw, names_start)
            indices = self._remember(raw[names_start:names_end], names)
            name_count = len(names)
        count_at = _HEADER_BYTES + _aligned(names_end - _HEADER_BYTES, 4)
        position_count = _UINT32.unpack_from(raw, count_at)[0]
        if indices is None or position_count != name_count:
            return None, name_count, position_count
        data_at = _HEADER_BYTES + _aligned(count_at + 4 - _HEADER_BYTES, 8)
        return np.frombuffer(raw, '<f8', position_count, data_at)[indices], name_count, position_count

    def _remember(self, block: bytes, names: tuple[str, ...]) -> np.ndarray | None:
        self._name_block, self._name_count = bytes(block), len(names)
        self._indices = _indices_of(self.joint_names, names)
        return self._indices

    def _select(self, names: tuple[str, ...], positions: np.ndarray, position_count: int):
        indices = _indices_of(self.joint_names, names)
        if indices is None or position_count != len(names):
            return None, len(names), position_count
        return positions[indices], len(names), position_count


def _indices_of(wanted: tuple[str, ...], names: tuple[str, ...]) -> np.ndarray | None:
    """Where each wanted joint is among `names`, or None if one is missing."""
    try:
        return np.array([names.index(n) for n in wanted])
    except ValueError:
        return None


def _read_strings(raw: bytes, at: int) -> tuple[tuple[str, ...], int]:
    """A CDR sequence<string> starting at byte `at` (4-aligned): the strings and the byte after them."""
    count = _UINT32.unpack_from(raw, at)[0]
    at += 4
    names = []
    for _ in range(count):
        at = _HEADER_BYTES + _aligned(at - _HEADER_BYTES, 4)
        size = _UINT32.unpack_from(raw, at)[0]    # includes the terminating NUL
        if size == 0 or at + 4 + size > len(raw):
            raise ValueError('string runs past the message')
        names.append(raw[at + 4:at + 3 + size].decode('utf-8'))
        at += 4 + size
    return tuple(names), at
