"""The one UR5 + table-tennis paddle model (docs/DESIGN.md, "One source of truth").

The robot is the example-robot-data UR5 URDF, unchanged, plus a paddle fixed on `tool0`. The URDF is
generated here at run time (the mesh directory depends on where example-robot-data is installed) and
the same XML is loaded by Pinocchio (FDCC, batched forward kinematics) and MuJoCo (the cell).

Frames added to the upstream model:
  paddle         the paddle body: handle along tool0 +z, blade beyond it; carries the paddle's mass.
  paddle_centre  centre of the blade; its z axis is the blade's face normal (tool0 +x), its y axis
                 is tool0 -y and its x axis points along the handle, away from the flange (tool0 +z).
All lengths are metres, masses kilograms, angles radians.
"""

from __future__ import annotations

import functools
import pathlib
import sys
import sysconfig
import xml.etree.ElementTree as ET
from dataclasses import dataclass

import numpy as np

JOINT_NAMES: tuple[str, ...] = (
    'shoulder_pan_joint',
    'shoulder_lift_joint',
    'elbow_joint',
    'wrist_1_joint',
    'wrist_2_joint',
    'wrist_3_joint',
)
NUM_JOINTS = len(JOINT_NAMES)
BASE_FRAME = 'base_link'
TOOL_FRAME = 'tool0'
PADDLE_BODY = 'paddle'
PADDLE_CENTRE_FRAME = 'paddle_centre'


@dataclass(frozen=True)
class PaddleSpec:
    """A standard table-tennis bat on a short adapter handle, clamped to the tool flange."""

    blade_radius_m: float = 0.075
    blade_thickness_m: float = 0.015  # wood plus both rubbers and sponge
    blade_mass_kg: float = 0.12
    handle_length_m: float = 0.10  # flange to the blade's edge
    handle_radius_m: float = 0.015
    handle_mass_kg: float = 0.05

    @property
    def mass_kg(self) -> float:
        return self.blade_mass_kg + self.handle_mass_kg

    @property
    def centre_offset_m(self) -> float:
        """Distance along tool0 +z from the flange to the blade centre."""
        return self.handle_length_m + self.blade_radius_m


PADDLE = PaddleSpec()


def example_robot_data_dir() -> pathlib.Path:
    """`share/example-robot-data` of the example-robot-data wheel (cmeel installs it under site-packages)."""
    relative = 'cmeel.prefix/share/example-robot-data'
    candidates = [pathlib.Path(sysconfig.get_paths()['purelib']) / relative]
    candidates += [pathlib.Path(p) / relative for p in sys.path if p]
    for path in candidates:
        if (path / 'robots/ur_description/urdf/ur5_robot.urdf').is_file():
            return path
    raise FileNotFoundError(
        'example-robot-data is not installed (pip install example-robot-data); looked in '
        + ', '.join(dict.fromkeys(str(c) for c in candidates))
    )


def _cylinder_inertia(mass_kg: float, radius_m: float, length_m: float) -> tuple[float, float]:
    """(about the axis, about a diameter through the centre) of a solid cylinder."""
    axial = 0.5 * mass_kg * radius_m**2
    transverse = mass_kg * (3.0 * radius_m**2 + length_m**2) / 12.0
    return axial, transverse


def _paddle_inertial(p: PaddleSpec) -> tuple[np.ndarray, np.ndarray]:
    """Centre of mass (tool0 frame) and inertia about it of handle + blade."""
    handle_com = np.array([0.0, 0.0, p.handle_length_m / 2.0])
    blade_com = np.array([0.0, 0.0, p.centre_offset_m])
    com = (p.handle_mass_kg * handle_com + p.blade_mass_kg * blade_com) / p.mass_kg
    # handle: axis along z; blade: axis (face normal) along x.
    h_axial, h_trans = _cylinder_inertia(p.handle_mass_kg, p.handle_radius_m, p.handle_length_m)
    b_axial, b_trans = _cylinder_inertia(p.blade_mass_kg, p.blade_radius_m, p.blade_thickness_m)
    inertia = np.diag([h_trans, h_trans, h_axial]) + np.diag([b_axial, b_trans, b_trans])
    for mass, c in ((p.handle_mass_kg, handle_com), (p.blade_mass_kg, blade_com)):
        d = c - com  # parallel axis theorem
        inertia += mass * (np.dot(d, d) * np.eye(3) - np.outer(d, d))
    return com, inertia


def _fmt(values) -> str:
    return ' '.join(repr(float(v)) for v in values)


def _add_paddle(robot: ET.Element, p: PaddleSpec) -> None:
    com, inertia = _paddle_inertial(p)
    link = ET.SubElement(robot, 'link', name=PADDLE_BODY)
    inertial = ET.SubElement(link, 'inertial')
    ET.SubElement(inertial, 'origin', xyz=_fmt(com), rpy='0 0 0')
    ET.SubElement(inertial, 'mass', value=repr(float(p.mass_kg)))
    entries = {'ixx': (0, 0), 'ixy': (0, 1), 'ixz': (0, 2), 'iyy': (1, 1), 'iyz': (1, 2), 'izz': (2, 2)}
    ET.SubElement(inertial, 'inertia', {k: repr(float(inertia[ij])) for k, ij in entries.items()})
    shapes = (
        ('paddle_handle', _fmt([0, 0, p.handle_length_m / 2]), '0 0 0', p.handle_radius_m, p.handle_length_m),
        # URDF cylinders lie along their z axis: turn the blade's axis onto tool0 x.
        (
            'paddle_blade',
            _fmt([0, 0, p.centre_offset_m]),
            _fmt([0, np.pi / 2, 0]),
            p.blade_radius_m,
            p.blade_thickness_m,
        ),
    )
    for tag in ('visual', 'collision'):
        for name, xyz, rpy, radius, length in shapes:
            element = ET.SubElement(link, tag, name=name)
            ET.SubElement(element, 'origin', xyz=xyz, rpy=rpy)
            geometry = ET.SubElement(element, 'geometry')
            ET.SubElement(geometry, 'cylinder', radius=repr(radius), length=repr(length))
    joint = ET.SubElement(robot, 'joint', name='tool0-paddle_fixed_joint', type='fixed')
    ET.SubElement(joint, 'parent', link=TOOL_FRAME)
    ET.SubElement(joint, 'child', link=PADDLE_BODY)
    ET.SubElement(joint, 'origin', xyz='0 0 0', rpy='0 0 0')

    ET.SubElement(robot, 'link', name=PADDLE_CENTRE_FRAME)
    joint = ET.SubElement(robot, 'joint', name='paddle-paddle_centre_fixed_joint', type='fixed')
    ET.SubElement(joint, 'parent', link=PADDLE_BODY)
    ET.SubElement(joint, 'child', link=PADDLE_CENTRE_FRAME)
    # z onto tool0 +x (the face normal), x onto tool0 +z (along the handle).
    ET.SubElement(joint, 'origin', xyz=_fmt([0, 0, p.centre_offset_m]), rpy=_fmt([0, np.pi / 2, 0]))


@functools.lru_cache(maxsize=None)
def urdf_xml(paddle: PaddleSpec = PADDLE) -> str:
    """The UR5 + paddle URDF, with a <mujoco> block (ignored by other parsers) for MuJoCo's importer."""
    share = example_robot_data_dir()
    tree = ET.parse(share / 'robots/ur_description/urdf/ur5_robot.urdf')
    robot = tree.getroot()
    robot.set('name', 'ur5_paddle')
    for tag in ('gazebo', 'transmission'):
        for element in robot.findall(tag):
            robot.remove(element)
    # The upstream "world" root link and its joint: the cell places the base itself (world spec).
    for element in list(robot):
        if (element.tag == 'link' and element.get('name') == 'world') or (
            element.tag == 'joint' and element.get('name') == 'world_joint'
        ):
            robot.remove(element)
    _add_paddle(robot, paddle)
    mujoco = ET.SubElement(robot, 'mujoco')
    # Keep every URDF link as a body (paddle_centre must exist), take inertials as written, and load
    # only the STL collision meshes (MuJoCo cannot read the .dae visuals).
    ET.SubElement(
        mujoco,
        'compiler',
        meshdir=str(share / 'robots/ur_description/meshes/ur5/collision'),
        discardvisual='true',
        fusestatic='false',
        balanceinertia='false',
        strippath='true',
    )
    ET.indent(tree)
    return ET.tostring(robot, encoding='unicode')


MESH_PACKAGE_URI = 'package://example-robot-data/'


@functools.lru_cache(maxsize=None)
def urdf_xml_for_display(paddle: PaddleSpec = PADDLE) -> str:
    """urdf_xml() with its mesh URIs as absolute file:// URIs: what /robot_description carries.

    The upstream URDF names its meshes package://example-robot-data/..., which RViz, Foxglove and rerun
    can only resolve where example-robot-data is a ROS package; here it is a Python wheel, so the
    published description points at the wheel's files instead. Nothing else differs from urdf_xml().
    """
    return urdf_xml(paddle).replace(MESH_PACKAGE_URI, example_robot_data_dir().as_uri() + '/')


def pinocchio_model():
    """A fresh Pinocchio model of the UR5 + paddle (joint order = JOINT_NAMES), gravity as URDF default."""
    import pinocchio as pin

    model = pin.buildModelFromXML(urdf_xml())
    names = tuple(model.names[1:])
    if names != JOINT_NAMES:
        raise RuntimeError(f'unexpected joint order in the robot model: {names}')
    return model


def mujoco_model():
    """The robot alone as a compiled MuJoCo model, from the same URDF."""
    import mujoco

    return mujoco.MjModel.from_xml_string(urdf_xml())


@dataclass(frozen=True)
class JointLimits:
    """Per-joint limits in JOINT_NAMES order: the URDF's (`joint_limits()`), or the narrower ones a controller
    keeps its commands within (`for_commands`: the player's command limiter, drag_teach's safety layer).

    One type for both, so that every side reads the same fields; the URDF states no acceleration limit,
    so `acceleration_rad_s2` is None in its limits and set in a controller's.
    """

    lower_rad: np.ndarray
    upper_rad: np.ndarray
    velocity_rad_s: np.ndarray
    effort_nm: np.ndarray
    acceleration_rad_s2: np.ndarray | None = None

    @classmethod
    def for_commands(cls, position_margin_rad: float, velocity_scale: float, acceleration_rad_s2) -> JointLimits:
        """The URDF's limits narrowed for commands: positions by a margin on each side, velocities by a
        scale, plus per-joint acceleration limits (a sequence of NUM_JOINTS values)."""
        urdf = joint_limits()
        acceleration = np.asarray(acceleration_rad_s2, dtype=float)
        if acceleration.shape != (NUM_JOINTS,):
            raise ValueError(f'acceleration limits need {NUM_JOINTS} values, got shape {acceleration.shape}')
        return cls(
            lower_rad=urdf.lower_rad + position_margin_rad,
            upper_rad=urdf.upper_rad - position_margin_rad,
            velocity_rad_s=urdf.velocity_rad_s * velocity_scale,
            effort_nm=urdf.effort_nm.copy(),
            acceleration_rad_s2=acceleration,
        )


@dataclass(frozen=True)
class ToolLoad:
    """What hangs on the wrist's F/T sensor: total mass (kg) and centre of mass (m, tool0 frame) of the links
    fixed below tool0 (the paddle). drag_teach reads it from Pinocchio's model, the viewer from the URDF text
    it is sent; both compensate the sensor reading for the same load."""

    mass_kg: float
    com_m: np.ndarray


@functools.lru_cache(maxsize=1)
def joint_limits() -> JointLimits:
    """The URDF's limits, in JOINT_NAMES order."""
    model = pinocchio_model()
    return JointLimits(
        lower_rad=np.array(model.lowerPositionLimit),
        upper_rad=np.array(model.upperPositionLimit),
        velocity_rad_s=np.array(model.velocityLimit),
        effort_nm=np.array(model.effortLimit),
    )
