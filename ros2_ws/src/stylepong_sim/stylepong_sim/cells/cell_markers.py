"""The cell's table, net and ball as visualization_msgs markers in frame `world` (for RViz and Foxglove).

Geometry from world_spec, the one definition the physics uses. No rclpy here: the nodes publish the array.
"""

from __future__ import annotations

from visualization_msgs.msg import Marker, MarkerArray

from stylepong_description.robot_cell import FRAME_WORLD
from stylepong_sim import world_spec

NAMESPACE = 'cell'
TABLE_ID, NET_ID, BALL_ID = 0, 1, 2
TABLE_RGBA = (0.05, 0.25, 0.55, 1.0)
NET_RGBA = (0.95, 0.95, 0.95, 0.8)
BALL_RGBA = (1.0, 0.55, 0.0, 1.0)


def _marker(marker_id: int, shape: int, centre_m, size_m, rgba) -> Marker:
    marker = Marker(ns=NAMESPACE, id=marker_id, type=shape, action=Marker.ADD, frame_locked=False)
    marker.header.frame_id = FRAME_WORLD
    marker.pose.position.x, marker.pose.position.y, marker.pose.position.z = (float(v) for v in centre_m)
    marker.pose.orientation.w = 1.0
    marker.scale.x, marker.scale.y, marker.scale.z = (float(v) for v in size_m)
    marker.color.r, marker.color.g, marker.color.b, marker.color.a = rgba
    return marker


def table_marker() -> Marker:
    """The table top: a box whose upper face is the playing surface."""
    centre = (0.0, 0.0, world_spec.TABLE_HEIGHT_M - world_spec.TABLE_THICKNESS_M / 2.0)
    size = (world_spec.TABLE_LENGTH_M, world_spec.TABLE_WIDTH_M, world_spec.TABLE_THICKNESS_M)
    return _marker(TABLE_ID, Marker.CUBE, centre, size, TABLE_RGBA)


def net_marker() -> Marker:
    """The net: a thin box standing on the table across its middle."""
    low, high = world_spec.NET_BOX_LOW_M, world_spec.NET_BOX_HIGH_M
    centre = tuple((lo + hi) / 2.0 for lo, hi in zip(low, high))
    size = tuple(hi - lo for lo, hi in zip(low, high))
    return _marker(NET_ID, Marker.CUBE, centre, size, NET_RGBA)


def ball_marker(position_m) -> Marker:
    """The ball at position_m; None as position: a DELETE of the ball marker (no ball in play)."""
    if position_m is None:
        return Marker(ns=NAMESPACE, id=BALL_ID, action=Marker.DELETE)
    diameter = 2.0 * world_spec.BALL_RADIUS_M
    return _marker(BALL_ID, Marker.SPHERE, position_m, (diameter, diameter, diameter), BALL_RGBA)


def cell_markers(ball_position_m, stamp) -> MarkerArray:
    """Table, net and ball (or its DELETE), all stamped `stamp`."""
    markers = [table_marker(), net_marker(), ball_marker(ball_position_m)]
    for marker in markers:
        marker.header.frame_id = FRAME_WORLD
        marker.header.stamp = stamp
    return MarkerArray(markers=markers)
