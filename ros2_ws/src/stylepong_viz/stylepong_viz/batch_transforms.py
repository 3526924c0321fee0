"""Joint transforms and link poses for many joint vectors at once (no ROS here).

The viewer sends the arm in batches (a flush's frames as one column per joint) and draws the paddle's path
through them; stylepong_description.robot_state computes the same transforms one joint vector at a time
with quaternion walks, which at 30 frames a second was most of the viewer's drawing time. Here the frames
of a batch go through numpy together. The unit tests compare both.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from stylepong_description.robot_state import RobotState

ROTATING_TYPES = ('revolute', 'continuous')


def quaternions_multiply(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Row-wise a * b of (x, y, z, w) quaternions (either may be a single one)."""
    ax, ay, az, aw = np.moveaxis(np.asarray(a, dtype=float), -1, 0)
    bx, by, bz, bw = np.moveaxis(np.asarray(b, dtype=float), -1, 0)
    return np.stack(
        [
            aw * bx + ax * bw + ay * bz - az * by,
            aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw,
            aw * bw - ax * bx - ay * by - az * bz,
        ],
        axis=-1,
    )


def joint_rotations(state: RobotState, positions: np.ndarray) -> list[np.ndarray]:
    """Per moving joint, its transform's rotation (n, 4) (x, y, z, w) at positions (n, joints): what
    RobotState.moving_transforms gives, row by row. A revolute joint's translation is its origin's, whatever
    the position; refuses a prismatic joint (none on the arm), whose translation moves."""
    positions = np.atleast_2d(np.asarray(positions, dtype=float))
    out = []
    for k, joint in enumerate(state.moving_joints):
        if joint.type not in ROTATING_TYPES:
            raise ValueError(f'joint {joint.name!r} is {joint.type}: only rotating joints are batched')
        half = positions[:, k] / 2.0
        motion = np.concatenate([np.outer(np.sin(half), joint.axis), np.cos(half)[:, None]], axis=1)
        out.append(quaternions_multiply(joint.origin_xyzw, motion))
    return out


def _matrix_from_quaternion(q_xyzw: np.ndarray) -> np.ndarray:
    """The rotation matrix of a unit quaternion (x, y, z, w), by Pinocchio."""
    return pin.Quaternion(np.asarray(q_xyzw, dtype=float)).toRotationMatrix()


class LinkPoses:
    """The pose of one link in the URDF's root for many joint vectors at once (the paddle's path, the tool's
    orientation): the joints from the root to the link composed as batched 3x3 rotations, which costs a
    fraction of RobotState.link_pose_in_base's quaternion walk per frame (the same transforms; the unit
    tests compare them)."""

    def __init__(self, state: RobotState, link: str):
        by_child = {j.child: j for j in state.fixed_joints + state.moving_joints}
        moving_index = {j.name: k for k, j in enumerate(state.moving_joints)}
        chain = []
        while link in by_child:
            chain.append(by_child[link])
            link = by_child[link].parent
        # (origin rotation, origin translation, index into the joint vector or None, axis, joint type)
        self._steps = [
            (_matrix_from_quaternion(j.origin_xyzw), j.origin_xyz_m, moving_index.get(j.name), j.axis, j.type)
            for j in reversed(chain)
        ]

    def poses(self, positions: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """positions (n, joints) in RobotState.moving_joint_names order -> (translations (n, 3) m,
        rotations (n, 3, 3))."""
        positions = np.atleast_2d(np.asarray(positions, dtype=float))
        n = len(positions)
        rotation, translation = np.broadcast_to(np.eye(3), (n, 3, 3)), np.zeros((n, 3))
        for origin_rotation, origin_m, index, axis, kind in self._steps:
            translation = translation + rotation @ origin_m
            rotation = rotation @ origin_rotation
            if index is None:
                continue
            value = positions[:, index]
            if kind == 'prismatic':
                translation = translation + (rotation @ axis) * value[:, None]
                continue
            # Rodrigues: the rotation by `value` about the unit `axis`.
            k = np.array([[0.0, -axis[2], axis[1]], [axis[2], 0.0, -axis[0]], [-axis[1], axis[0], 0.0]])
            turn = np.eye(3) + np.sin(value)[:, None, None] * k + (1.0 - np.cos(value))[:, None, None] * (k @ k)
            rotation = rotation @ turn
        return translation, rotation
