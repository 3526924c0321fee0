"""Decoding one bag connection's JointState messages into arrays (no rclpy).

Each batch goes through the fast CDR reader (joint_state_cdr) when the bag's JointState definition is
the standard one, and any message it cannot lay out exactly through rosbags' deserializer with the
bag's own definition, else the ROS 2 Jazzy typestore (`GenericJointStateDecoder`). Only the JointState
definition is ever parsed, so bags whose other topics carry definitions rosbags cannot parse (service
events) still open. A message no decoder can read is counted as a failure and skipped.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from stylepong_recording.bag_errors import one_line
from stylepong_recording.joint_state_cdr import NS_PER_S, CdrLayoutError, JointStateCdrReader

JOINT_STATE_TYPES = ('sensor_msgs/msg/JointState', 'sensor_msgs/JointState')


def is_standard_joint_state(connection, jazzy_store) -> bool:
    """Whether the bag's JointState definition is the one the fast reader assumes.

    rosbag2 stores a RIHS01 hash (Iron and later) and/or the definition text; bags without either
    (Humble sqlite3) carry the standard type, which has not changed across ROS 2 releases.
    """
    digest = getattr(connection, 'digest', '') or ''
    if digest.startswith('RIHS01_'):
        return digest == jazzy_store.hash_rihs01('sensor_msgs/msg/JointState')
    msgdef = getattr(connection, 'msgdef', None)
    data = getattr(msgdef, 'data', '') if msgdef is not None else ''
    if not data:
        return True
    try:
        types = _types_from_definition(connection)
    except Exception:  # noqa: BLE001  an unparsable definition: trust the standard layout, per message checked
        return True
    for name in ('sensor_msgs/msg/JointState', 'std_msgs/msg/Header', 'builtin_interfaces/msg/Time'):
        if name in types and types[name] != jazzy_store.fielddefs.get(name):
            return False
    return True


def _types_from_definition(connection) -> dict:
    from rosbags.interfaces import MessageDefinitionFormat
    from rosbags.typesys import get_types_from_idl, get_types_from_msg

    msgdef = connection.msgdef
    if msgdef.format == MessageDefinitionFormat.MSG:
        return dict(get_types_from_msg(msgdef.data, connection.msgtype))
    if msgdef.format == MessageDefinitionFormat.IDL:
        separator = '=' * 80 + '\n'
        types: dict = {}
        parts = msgdef.data.split(separator)[1:] if msgdef.data.startswith(f'{separator}IDL: ') else [msgdef.data]
        for part in parts:
            idl = part.split('\n', 1)[1] if part.startswith('IDL: ') else part
            types.update(get_types_from_idl(idl))
        return types
    return {}


def _normalise_type_name(msgtype: str) -> str:
    return 'sensor_msgs/msg/JointState' if msgtype in JOINT_STATE_TYPES else msgtype


class GenericJointStateDecoder:
    """rosbags' deserializer for one connection: the bag's own definition, else the Jazzy typestore."""

    def __init__(self, connection, jazzy_store) -> None:
        from rosbags.typesys import Stores, get_typestore

        self.msgtype = _normalise_type_name(connection.msgtype)
        self.error: str | None = None
        try:
            types = _types_from_definition(connection)
        except Exception as error:  # noqa: BLE001
            types = {}
            self.error = f'definition in the bag is unparsable ({one_line(error)})'
        if types:
            self.store = get_typestore(Stores.EMPTY)
            self.store.register(types)
        else:
            self.store = jazzy_store

    def decode(self, raw: bytes) -> tuple[int, int, tuple[str, ...], np.ndarray, np.ndarray]:
        msg = self.store.deserialize_cdr(raw, self.msgtype)
        stamp = msg.header.stamp
        return (
            int(stamp.sec),
            int(stamp.nanosec),
            tuple(msg.name),
            np.asarray(msg.position, float),
            np.asarray(msg.velocity, float),
        )


@dataclass
class JointStateBlock:
    """Messages sharing one name list and array lengths, as arrays."""

    name_id: int
    stamp_ns: np.ndarray
    receive_ns: np.ndarray
    position: np.ndarray  # (n, P) in the message's own joint order
    velocity: np.ndarray  # (n, V); V is 0 when the messages carry no velocities


class JointStateCollector:
    """Decodes one connection's messages in batches into `JointStateBlock`s."""

    BATCH = 8192
    # Layouts tried per batch before the rest is read message by message (a driver has one).
    LAYOUT_TRIES = 3

    def __init__(self, connection, jazzy_store, fast: bool) -> None:
        self.cdr = JointStateCdrReader()
        self.fast = fast
        self.generic: GenericJointStateDecoder | None = None
        self.connection = connection
        self.jazzy_store = jazzy_store
        self.blocks: list[JointStateBlock] = []
        self.yielded = 0
        self.failed = 0
        self.first_failure: str | None = None

    def add_all(self, messages) -> int:
        """Decode (receive_time_ns, raw) pairs; returns how many were yielded (decoded or not).

        A storage that fails part-way raises, but what it gave until then is decoded and counted.
        """
        times: list[int] = []
        raws: list[bytes] = []
        try:
            for timestamp, raw in messages:
                times.append(timestamp)
                raws.append(raw)
                if len(raws) >= self.BATCH:
                    self.yielded += len(raws)
                    self._decode_batch(times, raws)
                    times, raws = [], []
        finally:
            self.yielded += len(raws)
            self._decode_batch(times, raws)
        return self.yielded

    def _decode_batch(self, times: list[int], raws: list[bytes]) -> None:
        if not raws:
            return
        receive = np.asarray(times, dtype=np.int64)
        pending = np.ones(len(raws), dtype=bool)
        slow: dict[tuple[int, int, int], list] = {}

        def decode_slowly(i: int) -> None:
            decoded = self._decode_one(raws[i])
            if decoded is not None:
                stamp_ns, name_id, pos, vel = decoded
                slow.setdefault((name_id, len(pos), len(vel)), []).append((stamp_ns, int(receive[i]), pos, vel))

        for _ in range(self.LAYOUT_TRIES if self.fast else 0):
            if not pending.any():
                break
            first = int(np.argmax(pending))
            try:
                layout, rows, stamps, pos, vel = self.cdr.read_batch(raws, raws[first])
            except CdrLayoutError:
                pending[first] = False
                decode_slowly(first)
                continue
            fresh = pending[rows]
            rows = rows[fresh]
            pending[rows] = False
            self.blocks.append(
                JointStateBlock(
                    name_id=layout.name_id,
                    stamp_ns=stamps[fresh],
                    receive_ns=receive[rows],
                    position=pos[fresh],
                    velocity=vel[fresh],
                )
            )
        for i in np.flatnonzero(pending):
            decode_slowly(int(i))
        for (name_id, n_pos, n_vel), items in slow.items():
            self.blocks.append(
                JointStateBlock(
                    name_id=name_id,
                    stamp_ns=np.array([x[0] for x in items], dtype=np.int64),
                    receive_ns=np.array([x[1] for x in items], dtype=np.int64),
                    position=np.array([x[2] for x in items], dtype=float).reshape(len(items), n_pos),
                    velocity=np.array([x[3] for x in items], dtype=float).reshape(len(items), n_vel),
                )
            )

    def _decode_one(self, raw: bytes) -> tuple[int, int, tuple, tuple] | None:
        fast_error = None
        if self.fast:
            try:
                return self.cdr.read(raw)
            except CdrLayoutError as error:
                fast_error = error
        if self.generic is None:
            self.generic = GenericJointStateDecoder(self.connection, self.jazzy_store)
        try:
            sec, nanosec, names, pos, vel = self.generic.decode(raw)
        except Exception as error:  # noqa: BLE001  any decoder failure is one bad message
            self.failed += 1
            if self.first_failure is None:
                reason = one_line(error)
                if self.generic.error:
                    reason += f'; {self.generic.error}'
                elif fast_error is not None:
                    reason += f' (fast reader: {one_line(fast_error)})'
                self.first_failure = reason
            return None
        return sec * NS_PER_S + nanosec, self.cdr.name_id_for(names), tuple(pos.tolist()), tuple(vel.tolist())
