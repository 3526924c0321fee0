"""The numbers drag_teach needs from a serialized JointState or WrenchStamped, read straight from the bytes.

drag_teach subscribes to both at 500 Hz with `raw=True`: building the Python message objects cost more
than the controller itself (about 27 us for a JointState and 40 us for a WrenchStamped, against 70 us for
a whole control cycle; benchmarks/40_drag_teach.py), and all it needs is the joint names, the positions
and six doubles. The layout is plain CDR, little endian as ROS 2 middlewares write it on these machines:
a 4-byte encapsulation header, then the fields in order, each aligned to its size from the start of the
body (8 for doubles). Anything else (big endian, a truncated buffer) is handed to rclpy's deserialiser,
so the readers below only ever take a shortcut, never a different answer. JointState is walked by the
bag reader's decoder (stylepong_recording.joint_state_cdr); the wrench, six doubles after a header, here.
"""

from __future__ import annotations

import struct

import numpy as np
from geometry_msgs.msg import WrenchStamped
from rclpy.serialization import deserialize_message
from sensor_msgs.msg import JointState

from stylepong_recording.joint_state_cdr import CdrLayoutError, JointStateCdrReader

_HEADER_BYTES = 4  # encapsulation: representation id (2 bytes), options (2 bytes)
_LITTLE_ENDIAN_CDR = (0x00, 0x01)
_STAMP_BYTES = 8  # builtin_interfaces/Time: int32 sec, uint32 nanosec
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

    The CDR walk is the bag reader's (`stylepong_recording.joint_state_cdr`), the one JointState decoder of
    the workspace; it decodes a name list once per distinct name block, and the joint indices of each
    name list are kept here.
    """

    def __init__(self, joint_names: tuple[str, ...]):
        self.joint_names = tuple(joint_names)
        self._cdr = JointStateCdrReader()
        self._indices: dict[int, np.ndarray | None] = {}

    def positions(self, raw: bytes) -> tuple[np.ndarray | None, int, int]:
        """(positions in `joint_names` order or None when a joint is missing, name count, position count)."""
        try:
            layout = self._cdr.layout(raw)
        except CdrLayoutError:
            msg = deserialize_message(raw, JointState)  # not the standard little-endian layout: rclpy reads it
            return self._select(tuple(msg.name), np.asarray(msg.position, dtype=float), len(msg.position))
        name_count, position_count = len(self._cdr.name_lists[layout.name_id]), layout.position_count
        indices = self._indices_for(layout.name_id)
        if indices is None or position_count != name_count:
            return None, name_count, position_count
        return (np.frombuffer(raw, '<f8', position_count, layout.position_offset)[indices], name_count, position_count)

    def _indices_for(self, name_id: int) -> np.ndarray | None:
        if name_id not in self._indices:
            self._indices[name_id] = _indices_of(self.joint_names, self._cdr.name_lists[name_id])
        return self._indices[name_id]

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
