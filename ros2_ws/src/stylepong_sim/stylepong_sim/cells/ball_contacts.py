"""Where, within one physics step of the MuJoCo cell, the ball first touches the table, the net or the blade.

One ball, numpy, float64. The cell flies the ball on a straight segment p0 -> p1 per step (for the blade,
the segment in the blade's moving frame) and asks here for the earliest contact on it:
* table top and the faces of net and blade: exact crossing times of the planes the ball's centre
  reaches when it touches them, so nothing tunnels through them at any speed;
* the net's top edge and ends, the blade's rim: the ball's end position against the obstacle; up to
  15 m/s relative speed the ball moves at most 15 mm per 1 ms step, less than its radius, so no contact
  is missed or seen from the wrong side.
Only the geometry of the world spec and the paddle is here. What needs MuJoCo (the blade's velocity at a
point, from the arm's Jacobian; the other robot links' meshes) stays in the cell, which hands the first
in as a function. The batched world finds the same contacts for N balls in torch (batched_world).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from stylepong_description import robot_model
from stylepong_sim import world_spec

TABLE, NET, PADDLE, ROBOT = 'table', 'net', 'paddle', 'robot'

_UP = np.array([0.0, 0.0, 1.0])
_ZERO3 = np.zeros(3)
_NET_LOW_M = np.array(world_spec.NET_BOX_LOW_M)
_NET_HIGH_M = np.array(world_spec.NET_BOX_HIGH_M)
BLADE_HALF_THICKNESS_M = robot_model.PADDLE.blade_thickness_m / 2.0
BLADE_RADIUS_M = robot_model.PADDLE.blade_radius_m
# The blade's bounding sphere about its centre: a ball further away cannot touch it.
_BLADE_BOUND_M = math.hypot(BLADE_RADIUS_M, BLADE_HALF_THICKNESS_M)

# A world point on the blade -> its velocity (m/s), at the step's end.
PointVelocity = Callable[[np.ndarray], np.ndarray]
# A pose: (position m, rotation 3x3 whose columns are the frame's axes in the world).
Pose = tuple[np.ndarray, np.ndarray]


@dataclass
class Contact:
    """A contact of the ball within a step."""

    kind: str  # TABLE | NET | PADDLE | ROBOT
    fraction: float  # of the step at which it happens
    centre_m: np.ndarray  # ball centre at the contact, on the surface
    normal: np.ndarray  # unit, out of the surface towards the ball
    surface_velocity_m_s: np.ndarray


def table_contact(p0: np.ndarray, p1: np.ndarray) -> Contact | None:
    """The ball's bottom crossing the table top's plane over the table."""
    if not (p0[2] >= world_spec.TABLE_CONTACT_HEIGHT_M > p1[2]):
        return None
    fraction = (p0[2] - world_spec.TABLE_CONTACT_HEIGHT_M) / (p0[2] - p1[2])
    centre = p0 + fraction * (p1 - p0)
    if not world_spec.on_table(centre[0], centre[1]):
        return None
    centre[2] = world_spec.TABLE_CONTACT_HEIGHT_M
    return Contact(TABLE, fraction, centre, _UP, _ZERO3)


def net_contact(p0: np.ndarray, p1: np.ndarray, v1: np.ndarray) -> Contact | None:
    """The ball crossing one of the net's faces, or its end position against the net's top edge and ends."""
    r, face_x = world_spec.BALL_RADIUS_M, world_spec.NET_FACE_CONTACT_X_M
    if (p0[0] > face_x and p1[0] > face_x) or (p0[0] < -face_x and p1[0] < -face_x):
        return None  # on one side of the net, not touching it
    for side in (-1.0, 1.0):  # the net's two faces: exact crossing of the plane x = side * face_x
        s0, s1 = side * p0[0], side * p1[0]
        if s0 >= face_x > s1:
            fraction = (s0 - face_x) / (s0 - s1)
            centre = p0 + fraction * (p1 - p0)
            if abs(centre[1]) <= _NET_HIGH_M[1] and _NET_LOW_M[2] < centre[2] <= _NET_HIGH_M[2]:
                centre[0] = side * face_x
                return Contact(NET, fraction, centre, np.array([side, 0.0, 0.0]), _ZERO3)
    # Top edge and ends: the ball's end position against the net's box.
    closest = np.clip(p1, _NET_LOW_M, _NET_HIGH_M)
    offset = p1 - closest
    distance = float(np.linalg.norm(offset))
    if distance >= r:
        return None
    normal = offset / distance if distance > 0.0 else np.array([math.copysign(1.0, p0[0]), 0.0, 0.0])
    if np.dot(v1, normal) >= 0.0:
        return None
    return Contact(NET, 1.0, closest + normal * r, normal, _ZERO3)


def paddle_contact(
    p0: np.ndarray, p1: np.ndarray, v1: np.ndarray, before: Pose, after: Pose, blade_point_velocity: PointVelocity
) -> Contact | None:
    """The ball against the blade (a disc), which moved from pose `before` to `after` in this step:
    a face crossed in the blade's frame, or the end position against the rim."""
    (c0, rot0), (c1, rot1) = before, after
    # Far from the blade's bounding sphere, even allowing for this step's motion of ball and blade?
    reach = _BLADE_BOUND_M + world_spec.BALL_RADIUS_M + float(np.linalg.norm(p1 - p0)) + float(np.linalg.norm(c1 - c0))
    offset = p1 - c1
    if offset @ offset > reach * reach:
        return None
    local0 = rot0.T @ (p0 - c0)  # ball centre in the blade's frame (z = face normal) before the step
    local1 = rot1.T @ (p1 - c1)  # and after it: the segment between them is the relative motion
    h, radius, r = BLADE_HALF_THICKNESS_M, BLADE_RADIUS_M, world_spec.BALL_RADIUS_M
    face_z = h + r
    for side in (-1.0, 1.0):
        s0, s1 = side * local0[2], side * local1[2]
        if s0 >= face_z > s1:
            fraction = (s0 - face_z) / (s0 - s1)
            local = local0 + fraction * (local1 - local0)
            if local[0] ** 2 + local[1] ** 2 <= radius**2:
                local[2] = side * face_z
                normal = rot1[:, 2] * side
                centre = c1 + rot1 @ local
                surface_point = centre - normal * r
                return Contact(PADDLE, fraction, centre, normal, blade_point_velocity(surface_point))
    # Rim (and a ball found inside the blade's slab): the end position against the solid disc.
    rho = math.hypot(local1[0], local1[1])
    scale = min(1.0, radius / rho) if rho > 0.0 else 1.0
    closest = np.array([local1[0] * scale, local1[1] * scale, min(max(local1[2], -h), h)])
    offset = local1 - closest
    distance = float(np.linalg.norm(offset))
    if distance >= r:
        return None
    if distance > 0.0:
        local_normal = offset / distance
    else:
        local_normal = np.array([0.0, 0.0, math.copysign(1.0, local0[2])])
    normal = rot1 @ local_normal
    surface_point = c1 + rot1 @ closest
    u = blade_point_velocity(surface_point)
    if np.dot(v1 - u, normal) >= 0.0:
        return None
    return Contact(PADDLE, 1.0, surface_point + normal * r, normal, u)


def earliest_contact(
    p0: np.ndarray,
    p1: np.ndarray,
    v1: np.ndarray,
    blade_before: Pose,
    blade_after: Pose,
    blade_point_velocity: PointVelocity,
) -> Contact | None:
    """The first of the table, net and blade contacts within the step (None: none of them)."""
    candidates = [
        c
        for c in (
            table_contact(p0, p1),
            net_contact(p0, p1, v1),
            paddle_contact(p0, p1, v1, blade_before, blade_after, blade_point_velocity),
        )
        if c is not None
    ]
    return min(candidates, key=lambda c: c.fraction) if candidates else None
