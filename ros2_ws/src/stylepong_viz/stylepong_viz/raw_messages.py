"""Stamps and joint values read straight from serialized messages, for the live viewer (no rclpy here).

The viewer subscribes to the 500 Hz streams with `raw=True`: building a Python message object costs tens of
microseconds (benchmarks/40_drag_teach.py), and the viewer keeps one message in ten or more. So each
message's stamp is read from its first bytes (every drawn high-rate message starts with a std_msgs/Header),
and only a kept message is decoded: JointState by the workspace's one CDR walker
(stylepong_recording.joint_state_cdr), the others by rclpy in the node. A message not in little-endian CDR
(no stamp here, a CdrLayoutError) is handed to rclpy's deserialiser by the caller.
"""

from __future__ import annotations

import struct

from stylepong_recording.joint_state_cdr import JointStateCdrReader

_LITTLE_ENDIAN_CDR = b'\x00\x01'
_STAMP = struct.Struct('<iI')  # builtin_interfaces/Time: int32 sec, uint32 nanosec
_ENCAPSULATION_BYTES = 4


def header_stamp_s(raw: bytes) -> float | None:
    """The header stamp (s) of a serialized message that starts with a std_msgs/Header; None when the bytes
    are not little-endian CDR or too short to hold one."""
    if len(raw) < _ENCAPSULATION_BYTES + _STAMP.size or raw[:2] != _LITTLE_ENDIAN_CDR:
        return None
    sec, nanosec = _STAMP.unpack_from(raw, _ENCAPSULATION_BYTES)
    return sec + nanosec * 1e-9


class JointStateBytes:
    """(names, positions, velocities) of serialized sensor_msgs/JointState messages.

    read() raises stylepong_recording.joint_state_cdr.CdrLayoutError for bytes it cannot lay out.
    """

    def __init__(self) -> None:
        self._reader = JointStateCdrReader()

    def read(self, raw: bytes) -> tuple[tuple[str, ...], tuple[float, ...], tuple[float, ...]]:
        _, name_id, positions, velocities = self._reader.read(raw)
        return self._reader.name_lists[name_id], positions, velocities
