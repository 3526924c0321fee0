"""sensor_msgs/JointState read straight from its CDR bytes: stamp, names, positions, velocities (no rclpy).

This is the fast path of reading a bag, there for throughput: rosbags' generic deserializer builds a
full message object per message, which caps a dataset build at the deserializer's rate.
`JointStateCdrReader` reads only the stamp, the names (once per distinct name list) and the
position/velocity doubles, and raises CdrLayoutError for any message it cannot lay out exactly, which
the caller then hands to the generic deserializer (joint_state_decoding).
"""

from __future__ import annotations

import struct
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

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
        raw = bytes(block[offset + 4 : offset + 4 + length])
        names.append(raw.rstrip(b'\x00').decode('utf-8', errors='replace'))
        offset += 4 + length
    return tuple(names)


@dataclass(frozen=True)
class CdrLayout:
    """Where one message's fields lie (byte offsets from the start of the message)."""

    size: int
    name_id: int
    layout_bytes: tuple[tuple[int, int], ...]  # (start, stop) spans that fix every offset below
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
        self._last_layout: CdrLayout | None = None
        self._last_raw = b''

    def layout(self, raw: bytes) -> CdrLayout:
        """Where `raw`'s fields lie: the previous message's layout when `raw` has its length and every byte
        that decides an offset (a live topic's messages nearly always do), else a fresh walk."""
        last = self._last_layout
        if (
            last is not None
            and len(raw) == last.size
            and all(raw[start:stop] == self._last_raw[start:stop] for start, stop in last.layout_bytes)
        ):
            return last
        try:
            layout = self._layout(raw)
        except struct.error as error:
            raise CdrLayoutError(f'message too short ({len(raw)} bytes): {error}') from None
        self._last_layout, self._last_raw = layout, bytes(raw)
        return layout

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
            block = raw[start : _PAYLOAD + pos]
            name_id = self._name_ids.get(block)
            if name_id is None:
                name_id = self._name_ids[block] = len(self.name_lists)
                self.name_lists.append(_decode_names(block))
            self._last_block, self._last_id = block, name_id
        spans = [(0, _PAYLOAD), (_PAYLOAD + 8, _PAYLOAD + 12), (start, _PAYLOAD + pos)]
        arrays = []
        for _ in range(3):  # position, velocity, effort
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
        return CdrLayout(
            size=len(raw),
            name_id=name_id,
            layout_bytes=tuple(spans),
            position_offset=arrays[0][0],
            position_count=arrays[0][1],
            velocity_offset=arrays[1][0],
            velocity_count=arrays[1][1],
        )

    def read(self, raw: bytes) -> tuple[int, int, tuple, tuple]:
        """(stamp_ns, name_id, positions, velocities) of one message."""
        layout = self.layout(raw)
        sec, nanosec = _STAMP.unpack_from(raw, _PAYLOAD)
        positions = _doubles(layout.position_count).unpack_from(raw, layout.position_offset)
        velocities = _doubles(layout.velocity_count).unpack_from(raw, layout.velocity_offset)
        return sec * NS_PER_S + nanosec, layout.name_id, positions, velocities

    def read_batch(
        self, raws: Sequence[bytes], template: bytes
    ) -> tuple[CdrLayout, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Messages laid out like `template`: (layout, row indices, stamps_ns, positions, velocities)."""
        layout = self.layout(template)
        lengths = np.fromiter(map(len, raws), dtype=np.int64, count=len(raws))
        rows = np.flatnonzero(lengths == layout.size)
        matrix = np.frombuffer(b''.join([raws[i] for i in rows]), dtype=np.uint8).reshape(len(rows), layout.size)
        columns = np.concatenate([np.arange(a, b) for a, b in layout.layout_bytes])
        same = (matrix[:, columns] == np.frombuffer(template, dtype=np.uint8)[columns]).all(axis=1)
        rows, matrix = rows[same], matrix[same]
        sec = np.ascontiguousarray(matrix[:, _PAYLOAD : _PAYLOAD + 4]).view('<i4').ravel().astype(np.int64)
        nanosec = np.ascontiguousarray(matrix[:, _PAYLOAD + 4 : _PAYLOAD + 8]).view('<u4').ravel().astype(np.int64)

        def doubles(offset: int, count: int) -> np.ndarray:
            return np.ascontiguousarray(matrix[:, offset : offset + 8 * count]).view('<f8').reshape(len(rows), count)

        return (
            layout,
            rows,
            sec * NS_PER_S + nanosec,
            doubles(layout.position_offset, layout.position_count),
            doubles(layout.velocity_offset, layout.velocity_count),
        )

    def name_id_for(self, names: Sequence[str]) -> int:
        """Register a name list decoded elsewhere (the generic deserializer)."""
        key = b'\xff' + '\x00'.join(names).encode()  # cannot collide with a CDR block (starts with a count)
        name_id = self._name_ids.get(key)
        if name_id is None:
            name_id = self._name_ids[key] = len(self.name_lists)
            self.name_lists.append(tuple(names))
        return name_id
