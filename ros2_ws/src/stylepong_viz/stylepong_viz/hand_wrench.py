"""The hand's wrench from the wrist sensor's reading, for display (no ROS, no Pinocchio here).

The F/T sensor reads everything the environment applies on the tool: the paddle's own weight, the hand,
contacts. What a person teaching the arm pushes with is the reading less the paddle's weight at the tool's
current orientation, the same compensation drag_teach applies before its controller
(stylepong_fdcc.wrench_conditioning: sensor convention tool0 axes, about tool0's origin). The paddle's mass
and centre of mass are read from the URDF the cell publishes, so both sides use the one description; the
unit tests check them against drag_teach's Pinocchio reading of the same model. drag_teach's tare (its
estimate of the sensor's bias), low-pass and deadband are its own and are not repeated here: the viewer
shows the physical push, and a sensor bias shows as a constant arrow.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET

import numpy as np

from stylepong_description.robot_model import ToolLoad
from stylepong_description.robot_state import RobotState, quaternion_multiply, rotate

STANDARD_GRAVITY_M_S2 = 9.81  # as the URDF's (Pinocchio's) default gravity


def tool_load_from_urdf(urdf_xml: str, tool_frame: str) -> ToolLoad:
    """The links rigidly attached below `tool_frame` (fixed joints only), their inertials combined.

    Raises ValueError when nothing with mass hangs there (a URDF without the paddle).
    """
    state = RobotState(urdf_xml)
    children: dict[str, list] = {}
    for joint in state.fixed_joints:
        children.setdefault(joint.parent, []).append(joint.transform())
    # Each link's pose in the tool frame, walking the fixed joints down from it.
    poses = {tool_frame: (np.zeros(3), np.array([0.0, 0.0, 0.0, 1.0]))}
    stack = [tool_frame]
    while stack:
        parent = stack.pop()
        origin, rotation = poses[parent]
        for t in children.get(parent, []):
            poses[t.child] = (
                origin + rotate(rotation, t.translation_m),
                quaternion_multiply(rotation, t.rotation_xyzw),
            )
            stack.append(t.child)
    total_kg, moment = 0.0, np.zeros(3)
    for link in ET.fromstring(urdf_xml).findall('link'):
        inertial = link.find('inertial')
        if link.get('name') not in poses or inertial is None or inertial.find('mass') is None:
            continue
        mass_kg = float(inertial.find('mass').get('value'))
        origin = inertial.find('origin')
        com_in_link = np.array(
            [float(v) for v in (origin.get('xyz', '0 0 0') if origin is not None else '0 0 0').split()]
        )
        position, rotation = poses[link.get('name')]
        total_kg += mass_kg
        moment += mass_kg * (position + rotate(rotation, com_in_link))
    if total_kg <= 0.0:
        raise ValueError(f'no link with a mass is fixed below {tool_frame!r} in the URDF')
    return ToolLoad(mass_kg=total_kg, com_m=moment / total_kg)


def hand_wrench_in_tool(
    reading_tool: np.ndarray, load: ToolLoad, tool_rotation_base: np.ndarray, gravity_base_m_s2: np.ndarray
) -> np.ndarray:
    """(force N, torque N m) the hand applies: the sensor reading (tool axes, about the tool origin) less the
    tool's weight at the tool's orientation in the base (3x3 rotation, tool axes to base axes)."""
    weight_tool = np.asarray(tool_rotation_base).T @ (load.mass_kg * np.asarray(gravity_base_m_s2, dtype=float))
    reading = np.asarray(reading_tool, dtype=float)
    return np.concatenate([reading[:3] - weight_tool, reading[3:] - np.cross(load.com_m, weight_tool)])
