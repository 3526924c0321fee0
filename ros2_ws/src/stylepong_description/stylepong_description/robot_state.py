"""Joint transforms of a URDF, the way robot_state_publisher computes them (no ROS imports here).

robot_state_publisher publishes, for every joint of the URDF, the transform from its parent link to its
child link: the fixed joints once on /tf_static, the moving ones on /tf whenever the joint positions
change. A joint's transform is its <origin> followed by the motion about (revolute, continuous) or along
(prismatic) its <axis>. This module holds that computation; stylepong_sim's nodes only put the results
into TransformStamped messages. Quaternions are (x, y, z, w), as in geometry_msgs; lengths metres.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from dataclasses import dataclass

import numpy as np

MOVING_TYPES = ('revolute', 'continuous', 'prismatic')


def quaternion_from_rpy(roll_rad: float, pitch_rad: float, yaw_rad: float) -> np.ndarray:
    """URDF's rpy (fixed axes: roll about x, then pitch about y, then yaw about z) as (x, y, z, w)."""
    cr, sr = np.cos(roll_rad / 2.0), np.sin(roll_rad / 2.0)
    cp, sp = np.cos(pitch_rad / 2.0), np.sin(pitch_rad / 2.0)
    cy, sy = np.cos(yaw_rad / 2.0), np.sin(yaw_rad / 2.0)
    return np.array(
        [
            sr * cp * cy - cr * sp * sy,
            cr * sp * cy + sr * cp * sy,
            cr * cp * sy - sr * sp * cy,
            cr * cp * cy + sr * sp * sy,
        ]
    )


def quaternion_multiply(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """The rotation a then b in a's frame (a * b), both (x, y, z, w)."""
    ax, ay, az, aw = a
    bx, by, bz, bw = b
    return np.array(
        [
            aw * bx + ax * bw + ay * bz - az * by,
            aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw,
            aw * bw - ax * bx - ay * by - az * bz,
        ]
    )


def quaternion_from_matrix(rotation: np.ndarray) -> np.ndarray:
    """A 3x3 rotation matrix as a unit quaternion (x, y, z, w) with w >= 0."""
    m = np.asarray(rotation, dtype=float)
    w = np.sqrt(max(0.0, 1.0 + m[0, 0] + m[1, 1] + m[2, 2])) / 2.0
    x = np.copysign(np.sqrt(max(0.0, 1.0 + m[0, 0] - m[1, 1] - m[2, 2])) / 2.0, m[2, 1] - m[1, 2])
    y = np.copysign(np.sqrt(max(0.0, 1.0 - m[0, 0] + m[1, 1] - m[2, 2])) / 2.0, m[0, 2] - m[2, 0])
    z = np.copysign(np.sqrt(max(0.0, 1.0 - m[0, 0] - m[1, 1] + m[2, 2])) / 2.0, m[1, 0] - m[0, 1])
    q = np.array([x, y, z, w])
    return q / np.linalg.norm(q)


def rotate(q: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Vector v rotated by the unit quaternion q (x, y, z, w)."""
    u, w = q[:3], q[3]
    return v + 2.0 * np.cross(u, np.cross(u, v) + w * v)


@dataclass(frozen=True)
class LinkTransform:
    """The pose of `child` in `parent`: translation (m) and rotation (x, y, z, w)."""

    parent: str
    child: str
    translation_m: np.ndarray
    rotation_xyzw: np.ndarray


@dataclass(frozen=True)
class UrdfJoint:
    """One <joint>: its links, origin (translation and rotation) and unit axis."""

    name: str
    type: str
    parent: str
    child: str
    origin_xyz_m: np.ndarray
    origin_xyzw: np.ndarray
    axis: np.ndarray
    velocity_limit: float = float('inf')  # <limit velocity>: rad/s (m/s prismatic); inf when absent

    def transform(self, position: float = 0.0) -> LinkTransform:
        """Parent link to child link at this joint position (rad, or m for prismatic; ignored when fixed)."""
        if self.type in ('revolute', 'continuous'):
            half = position / 2.0
            motion = np.concatenate([self.axis * np.sin(half), [np.cos(half)]])
            return LinkTransform(
                self.parent, self.child, self.origin_xyz_m, quaternion_multiply(self.origin_xyzw, motion)
            )
        if self.type == 'prismatic':
            shift = rotate(self.origin_xyzw, self.axis * position)
            return LinkTransform(self.parent, self.child, self.origin_xyz_m + shift, self.origin_xyzw)
        return LinkTransform(self.parent, self.child, self.origin_xyz_m, self.origin_xyzw)


def _floats(text: str | None, default: tuple[float, float, float]) -> np.ndarray:
    return np.array([float(v) for v in text.split()]) if text else np.array(default, dtype=float)


def parse_joints(urdf_xml: str) -> tuple[UrdfJoint, ...]:
    """Every <joint> of the URDF, in document order. Raises ValueError on a joint without parent or child."""
    joints = []
    for element in ET.fromstring(urdf_xml).findall('joint'):
        name, kind = element.get('name'), element.get('type')
        parent, child = element.find('parent'), element.find('child')
        if parent is None or child is None:
            raise ValueError(f'URDF joint {name!r} has no parent or no child link')
        origin = element.find('origin')
        xyz = _floats(origin.get('xyz') if origin is not None else None, (0.0, 0.0, 0.0))
        rpy = _floats(origin.get('rpy') if origin is not None else None, (0.0, 0.0, 0.0))
        axis_element = element.find('axis')
        axis = _floats(axis_element.get('xyz') if axis_element is not None else None, (1.0, 0.0, 0.0))
        limit = element.find('limit')
        velocity_limit = float(limit.get('velocity', 'inf')) if limit is not None else float('inf')
        joints.append(
            UrdfJoint(
                name=name,
                type=kind,
                parent=parent.get('link'),
                child=child.get('link'),
                origin_xyz_m=xyz,
                origin_xyzw=quaternion_from_rpy(*rpy),
                axis=axis / np.linalg.norm(axis),
                velocity_limit=velocity_limit,
            )
        )
    return tuple(joints)


class RobotState:
    """The transforms robot_state_publisher would publish for a URDF: fixed ones, and moving ones per joint state."""

    def __init__(self, urdf_xml: str):
        joints = parse_joints(urdf_xml)
        self.fixed_joints = tuple(j for j in joints if j.type not in MOVING_TYPES)
        self.moving_joints = tuple(j for j in joints if j.type in MOVING_TYPES)
        self._index_by_name = {j.name: k for k, j in enumerate(self.moving_joints)}

    @property
    def moving_joint_names(self) -> tuple[str, ...]:
        return tuple(j.name for j in self.moving_joints)

    def link_pose_in_base(self, link: str, positions: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(translation m, rotation xyzw) of `link` in the URDF's root link, moving joints at `positions`."""
        by_child = {t.child: t for t in self.fixed_transforms() + self.moving_transforms(positions)}
        chain = []
        while link in by_child:
            chain.append(by_child[link])
            link = by_child[link].parent
        translation, rotation = np.zeros(3), np.array([0.0, 0.0, 0.0, 1.0])
        for t in reversed(chain):
            translation = translation + rotate(rotation, t.translation_m)
            rotation = quaternion_multiply(rotation, t.rotation_xyzw)
        return translation, rotation

    def fixed_transforms(self) -> list[LinkTransform]:
        """For /tf_static: one per fixed joint."""
        return [j.transform() for j in self.fixed_joints]

    def moving_transforms(self, positions: np.ndarray) -> list[LinkTransform]:
        """For /tf: one per moving joint, positions in moving_joint_names order."""
        return [j.transform(float(p)) for j, p in zip(self.moving_joints, positions)]

    def moving_transforms_by_name(self, names, positions) -> list[LinkTransform]:
        """For /tf from a JointState: the joints it names that this URDF moves (others ignored, like RSP)."""
        out = []
        for name, position in zip(names, positions):
            k = self._index_by_name.get(name)
            if k is not None:
                out.append(self.moving_joints[k].transform(float(position)))
        return out
