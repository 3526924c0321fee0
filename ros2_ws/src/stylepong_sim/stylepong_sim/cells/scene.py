"""The cell's MuJoCo model: the one UR5 + paddle URDF placed by the world spec, plus table, net, floor, ball.

Nothing here holds a number of its own: the robot comes from stylepong_description.robot_model, the
geometry, placement and servo constants from world_spec. `build_model()` returns a compiled MjModel
with these names (used by cell.py and the video recorder):
  geoms    table_top, net (collide with the robot only), floor, ball (a mocap sphere that collides
           with nothing: the cell handles the ball's contacts itself), paddle_blade, paddle_handle
  bodies   base_link ... wrist_3_link, tool0, paddle, paddle_centre (URDF links), ball (mocap)
  site     ft_sensor (tool0's origin and axes) with sensors ft_force, ft_torque
  actuators one per joint, named like the joint: the servo's PD law (see world_spec)
  camera   overview (a side view of the robot's half), robot_view (from behind the opponent's end)
Collision filtering: robot geoms (contype 1, conaffinity 2) touch the environment (contype 2,
conaffinity 1) but never each other (the URDF's collision meshes of neighbouring links overlap).
"""

from __future__ import annotations

import mujoco
import numpy as np

from stylepong_description import robot_model
from stylepong_sim import world_spec

ROBOT_CONTYPE, ROBOT_CONAFFINITY = 1, 2
ENV_CONTYPE, ENV_CONAFFINITY = 2, 1
FT_SITE = 'ft_sensor'
FT_FORCE_SENSOR = 'ft_force'
FT_TORQUE_SENSOR = 'ft_torque'
BALL_BODY = 'ball'
BALL_PARKING_POSITION_M = (0.0, 0.0, -1.0)  # under the floor, out of sight, while no ball is in play
CAMERAS = ('overview', 'robot_view')

_TABLE_RGBA = (0.05, 0.25, 0.55, 1.0)
_LINE_RGBA = (0.95, 0.95, 0.95, 1.0)
_NET_RGBA = (0.9, 0.9, 0.9, 0.8)
_BALL_RGBA = (1.0, 0.55, 0.0, 1.0)
_LINE_WIDTH_M = 0.02
_LEG_HALF_SIZE_M = 0.03


def _look_at_quat(position_m, target_m) -> list[float]:
    """Orientation of a MuJoCo camera (looking along its -z, y up) at position looking at target."""
    forward = np.asarray(target_m, float) - np.asarray(position_m, float)
    forward /= np.linalg.norm(forward)
    right = np.cross(forward, [0.0, 0.0, 1.0])
    right /= np.linalg.norm(right)
    up = np.cross(right, forward)
    return _quat_of(np.column_stack([right, up, -forward]))


def _quat_of(rotation: np.ndarray) -> list[float]:
    """MuJoCo's quaternion (w, x, y, z) of a rotation matrix."""
    quat = np.zeros(4)
    mujoco.mju_mat2Quat(quat, np.ascontiguousarray(rotation, dtype=float).ravel())
    return quat.tolist()


def _static_box(spec: mujoco.MjSpec, name: str, centre_m, half_size_m, rgba, collides: bool) -> None:
    spec.worldbody.add_geom(
        name=name,
        type=mujoco.mjtGeom.mjGEOM_BOX,
        pos=list(centre_m),
        size=list(half_size_m),
        rgba=list(rgba),
        contype=ENV_CONTYPE if collides else 0,
        conaffinity=ENV_CONAFFINITY if collides else 0,
    )


def _add_table_and_net(spec: mujoco.MjSpec) -> None:
    top_z = world_spec.TABLE_HEIGHT_M
    half_length_m, half_width_m = world_spec.HALF_LENGTH_M, world_spec.HALF_WIDTH_M
    _static_box(
        spec,
        'table_top',
        (0.0, 0.0, top_z - world_spec.TABLE_THICKNESS_M / 2.0),
        (half_length_m, half_width_m, world_spec.TABLE_THICKNESS_M / 2.0),
        _TABLE_RGBA,
        collides=True,
    )
    _static_box(
        spec,
        'net',
        (0.0, 0.0, top_z + world_spec.NET_HEIGHT_M / 2.0),
        (world_spec.NET_THICKNESS_M / 2.0, world_spec.NET_LENGTH_M / 2.0, world_spec.NET_HEIGHT_M / 2.0),
        _NET_RGBA,
        collides=True,
    )
    # Markings and legs: looks only.
    line_z = top_z + 0.0005
    for sign in (-1.0, 1.0):
        _static_box(
            spec,
            f'line_side_{int(sign):+d}',
            (0.0, sign * (half_width_m - _LINE_WIDTH_M / 2), line_z),
            (half_length_m, _LINE_WIDTH_M / 2, 0.0005),
            _LINE_RGBA,
            collides=False,
        )
        _static_box(
            spec,
            f'line_end_{int(sign):+d}',
            (sign * (half_length_m - _LINE_WIDTH_M / 2), 0.0, line_z),
            (_LINE_WIDTH_M / 2, half_width_m, 0.0005),
            _LINE_RGBA,
            collides=False,
        )
        for side in (-1.0, 1.0):
            leg_height = top_z - world_spec.TABLE_THICKNESS_M
            _static_box(
                spec,
                f'leg_{int(sign):+d}_{int(side):+d}',
                (sign * (half_length_m - 0.2), side * (half_width_m - 0.1), leg_height / 2),
                (_LEG_HALF_SIZE_M, _LEG_HALF_SIZE_M, leg_height / 2),
                (0.2, 0.2, 0.2, 1.0),
                collides=False,
            )
    _static_box(spec, 'centre_line', (0.0, 0.0, line_z), (half_length_m, 0.0015, 0.0005), _LINE_RGBA, collides=False)


def _add_pedestal(spec: mujoco.MjSpec) -> None:
    x, y, z = world_spec.ROBOT_BASE_POSITION_M
    hx, hy = world_spec.PEDESTAL_HALF_SIZE_M
    _static_box(spec, 'pedestal', (x, y, z / 2.0), (hx, hy, z / 2.0), (0.35, 0.35, 0.38, 1.0), collides=False)


def _add_ball(spec: mujoco.MjSpec) -> None:
    body = spec.worldbody.add_body(name=BALL_BODY, mocap=True, pos=list(BALL_PARKING_POSITION_M))
    body.add_geom(
        name='ball',
        type=mujoco.mjtGeom.mjGEOM_SPHERE,
        size=[world_spec.BALL_RADIUS_M, 0.0, 0.0],
        rgba=list(_BALL_RGBA),
        contype=0,
        conaffinity=0,
        mass=world_spec.BALL_MASS_KG,
    )


def _add_looks(spec: mujoco.MjSpec) -> None:
    kind, pattern = mujoco.mjtTexture, mujoco.mjtBuiltin
    # Square built-in textures: name, kind, pattern, side (pixels), its two colours.
    for name, texture_type, builtin, side_px, rgb1, rgb2 in (
        ('sky', kind.mjTEXTURE_SKYBOX, pattern.mjBUILTIN_GRADIENT, 64, [0.55, 0.6, 0.68], [0.12, 0.13, 0.16]),
        ('floor_grid', kind.mjTEXTURE_2D, pattern.mjBUILTIN_CHECKER, 256, [0.32, 0.32, 0.34], [0.27, 0.27, 0.29]),
    ):
        spec.add_texture(
            name=name, type=texture_type, builtin=builtin, width=side_px, height=side_px, rgb1=rgb1, rgb2=rgb2
        )
    material = spec.add_material(name='floor_grid', texrepeat=[8.0, 8.0])
    material.textures[mujoco.mjtTextureRole.mjTEXROLE_RGB] = 'floor_grid'
    spec.worldbody.add_geom(
        name='floor',
        type=mujoco.mjtGeom.mjGEOM_PLANE,
        size=[6.0, 5.0, 0.05],
        material='floor_grid',
        contype=ENV_CONTYPE,
        conaffinity=ENV_CONAFFINITY,
    )
    spec.worldbody.add_light(
        name='ceiling', pos=[-0.5, 0.0, 4.0], dir=[0.0, 0.0, -1.0], castshadow=False, diffuse=[0.7, 0.7, 0.7]
    )
    # Side view of the robot's half, and the opponent's view of the robot.
    for name, position, target in (
        ('overview', (-0.5, 2.3, 1.65), (-1.25, 0.0, 0.85)),
        ('robot_view', (2.6, 0.0, 1.9), (-1.5, 0.0, 0.8)),
    ):
        spec.worldbody.add_camera(name=name, pos=list(position), quat=_look_at_quat(position, target), fovy=55.0)


def _configure_robot(spec: mujoco.MjSpec) -> None:
    base = spec.body(robot_model.BASE_FRAME)
    rotation, position = world_spec.robot_base_pose()
    base.pos = position.tolist()
    base.quat = _quat_of(rotation)
    for body in spec.bodies:
        if body.name != 'world':
            body.gravcomp = 1.0  # ideal gravity compensation, in joint space (must be set before compiling)
    for geom in spec.geoms:
        geom.contype, geom.conaffinity = ROBOT_CONTYPE, ROBOT_CONAFFINITY
    limits = robot_model.joint_limits()
    for i, name in enumerate(robot_model.JOINT_NAMES):
        spec.joint(name).armature = world_spec.ARM_ARMATURE_KG_M2[i]
        kp, kd = world_spec.ARM_KP_NM_PER_RAD[i], world_spec.ARM_KD_NMS_PER_RAD[i]
        actuator = spec.add_actuator(name=name, target=name, trntype=mujoco.mjtTrn.mjTRN_JOINT)
        # force = Kp ctrl - Kp q - Kd qdot, clipped to the effort limit; ctrl = q_ref + (Kd/Kp) v_ref.
        actuator.gaintype = mujoco.mjtGain.mjGAIN_FIXED
        actuator.biastype = mujoco.mjtBias.mjBIAS_AFFINE
        actuator.gainprm[0] = kp
        actuator.biasprm[0:3] = [0.0, -kp, -kd]
        actuator.forcelimited = mujoco.mjtLimited.mjLIMITED_TRUE
        actuator.forcerange = [-float(limits.effort_nm[i]), float(limits.effort_nm[i])]
        actuator.ctrllimited = mujoco.mjtLimited.mjLIMITED_FALSE
    spec.body(robot_model.TOOL_FRAME).add_site(name=FT_SITE, pos=[0.0, 0.0, 0.0])
    for name, sensor_type in (
        (FT_FORCE_SENSOR, mujoco.mjtSensor.mjSENS_FORCE),
        (FT_TORQUE_SENSOR, mujoco.mjtSensor.mjSENS_TORQUE),
    ):
        spec.add_sensor(name=name, type=sensor_type, objtype=mujoco.mjtObj.mjOBJ_SITE, objname=FT_SITE)


def build_spec() -> mujoco.MjSpec:
    """The cell's MuJoCo spec: the robot from the URDF, with table, net, pedestal, ball and cameras."""
    spec = mujoco.MjSpec.from_string(robot_model.urdf_xml())
    spec.modelname = 'stylepong_cell'
    # The URDF's <mujoco> block discards visual geoms (the .dae meshes MuJoCo cannot read) while
    # parsing; keep the cell's own visual-only geoms (markings, ball, pedestal) at compile time.
    spec.compiler.discardvisual = False
    spec.option.timestep = world_spec.PHYSICS_DT_S
    spec.option.gravity = [0.0, 0.0, -world_spec.GRAVITY_M_S2]
    spec.option.integrator = mujoco.mjtIntegrator.mjINT_IMPLICITFAST
    spec.visual.global_.offwidth = 1920
    spec.visual.global_.offheight = 1080
    _configure_robot(spec)  # before anything else is added: it touches every geom and body present
    _add_table_and_net(spec)
    _add_pedestal(spec)
    _add_ball(spec)
    _add_looks(spec)
    return spec


def build_model() -> mujoco.MjModel:
    """The cell's compiled MuJoCo model."""
    return build_spec().compile()
