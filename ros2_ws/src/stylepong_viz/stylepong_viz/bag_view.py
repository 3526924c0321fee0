"""A recorded clip (rosbag2, mcap or sqlite3) into a CellView: the same view as live, from the bag's messages.

rosbags reads both storage formats and the type definitions stored in the bag (old sqlite3 bags without
them fall back to Jazzy's standard types). Times are header stamps where a message has one, else the
bag's receive time, as in the live view.
"""

from __future__ import annotations

import json
import pathlib

from stylepong_sim.referee import EVENT_NAMES
from stylepong_viz.cell_view import CellView, stamp_seconds

# The topics drawn, by type; other topics in the bag are skipped.
DRAWN_TYPES = {
    'sensor_msgs/msg/JointState',
    'std_msgs/msg/Float64MultiArray',
    'stylepong_msgs/msg/BallState',
    'geometry_msgs/msg/WrenchStamped',
    'stylepong_msgs/msg/RallyEvent',
    'std_msgs/msg/String',
}


FLUSH_PERIOD_S = 0.1


class BagError(RuntimeError):
    """The bag is missing, damaged or holds nothing to show; the message is one line naming it."""


def _open_reader(path: pathlib.Path):
    from rosbags.highlevel import AnyReader, AnyReaderError
    from rosbags.typesys import Stores, get_typestore

    if not path.exists():
        raise BagError(f'bag {path} does not exist')
    try:
        reader = AnyReader([path], default_typestore=get_typestore(Stores.ROS2_JAZZY))
        reader.open()
    except AnyReaderError as error:
        raise BagError(f'bag {path} cannot be read: {" ".join(str(error).split())}') from error
    except Exception as error:  # noqa: BLE001 - a damaged file fails in many ways inside the storage readers
        raise BagError(f'bag {path} is damaged: {type(error).__name__}: {" ".join(str(error).split())}') from error
    return reader


def show_bag(path: pathlib.Path, view: CellView) -> dict[str, int]:
    """Feed every drawable message of the bag into `view`; returns the counts per topic."""
    reader = _open_reader(path)
    counts: dict[str, int] = {}
    flushed_s = 0.0
    try:
        connections = [c for c in reader.connections if c.msgtype in DRAWN_TYPES]
        if not any(c.msgtype == 'sensor_msgs/msg/JointState' for c in connections):
            raise BagError(
                f'bag {path} has no sensor_msgs/JointState topic to show '
                f'(topics: {", ".join(sorted({c.topic for c in reader.connections})) or "none"})'
            )
        try:
            for connection, receive_ns, raw in reader.messages(connections=connections):
                msg = reader.deserialize(raw, connection.msgtype)
                _dispatch(view, connection.topic, connection.msgtype, msg, receive_ns * 1e-9)
                counts[connection.topic] = counts.get(connection.topic, 0) + 1
                # As live: a batch per FLUSH_PERIOD_S of message time (a clip that starts again: at once).
                if not 0.0 <= view.latest_time_s - flushed_s < FLUSH_PERIOD_S:
                    view.flush()
                    flushed_s = view.latest_time_s
        except BagError:
            raise
        except Exception as error:  # noqa: BLE001 - truncated chunks, corrupt records
            raise BagError(
                f'bag {path} is damaged after {sum(counts.values())} messages: '
                f'{type(error).__name__}: {" ".join(str(error).split())}'
            ) from error
        view.flush()
    finally:
        reader.close()
    if not counts.get(next(c.topic for c in connections if c.msgtype == 'sensor_msgs/msg/JointState'), 0):
        raise BagError(f'bag {path} holds no joint states')
    return counts


def _dispatch(view: CellView, topic: str, msgtype: str, msg, receive_s: float) -> None:
    if msgtype == 'sensor_msgs/msg/JointState':
        view.on_joint_state(stamp_seconds(msg.header), lambda: (list(msg.name), list(msg.position), list(msg.velocity)))
    elif msgtype == 'std_msgs/msg/Float64MultiArray' and topic.endswith('/commands'):
        view.on_command(lambda: [float(v) for v in msg.data])
    elif msgtype == 'stylepong_msgs/msg/BallState':
        view.on_ball(stamp_seconds(msg.header), lambda: (msg.position.x, msg.position.y, msg.position.z))
    elif msgtype == 'geometry_msgs/msg/WrenchStamped':
        f, t = msg.wrench.force, msg.wrench.torque
        view.on_wrench(stamp_seconds(msg.header), lambda: (f.x, f.y, f.z, t.x, t.y, t.z))
    elif msgtype == 'stylepong_msgs/msg/RallyEvent':
        p = msg.position
        view.on_rally_event(
            stamp_seconds(msg.header),
            EVENT_NAMES.get(msg.type, str(msg.type)),
            msg.reason,
            msg.success,
            (p.x, p.y, p.z),
        )
    elif msgtype == 'std_msgs/msg/String' and topic == '/player/status':
        try:
            view.on_player_status(view.latest_time_s, json.loads(msg.data))
        except (ValueError, AttributeError):
            pass  # a malformed status is not drawn
