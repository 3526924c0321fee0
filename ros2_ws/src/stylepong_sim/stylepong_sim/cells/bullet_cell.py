"""The table-tennis cell in PyBullet: a second cell that shares no physics code with training, free of ROS.

Same API as cell.Cell (what ur5_sim's node and the tests use), so `ur5_sim --ros-args -p engine:=pybullet`
(or `ros2 run stylepong_sim ur5_bullet`) serves the same topics from it:
    cell = BulletCell(home_joint_positions_rad, actuator='ideal'|'ur_servoj', servoj=ServojSettings(...))
    reset(), set_joint_targets(q), set_hand_wrench(force, torque, frame, duration_s), clear_hand_wrench(),
    launch_ball(p, v) -> ball_id, remove_ball(), step(n), step_for(s), time_s, dt_s, joint_positions_rad,
    joint_velocities_rad_s, joint_efforts_nm, joint_targets_rad, tool_wrench(include_inertia), ball_in_play,
    ball_id, ball_position_m, ball_velocity_m_s, pop_events(), paddle_pose(), tool_pose()

What is Bullet's and what is shared with the other simulators:
* shared: the URDF and paddle (stylepong_description), the world spec's geometry, masses and coefficients,
  the referee's rules (referee.Referee), the actuator models (ur_servoj.py: the command -> reference law),
  the API's input checks and bookkeeping (cell_base.CellBase, the MuJoCo cell's base too);
* Bullet's own: the arm's multibody dynamics (Featherstone) and its joint motors, which track the reference
  as velocity constraints within the URDF efforts; the ball as a rigid sphere with spin, its contacts with
  table, net, paddle and arm from Bullet's collision detection and constraint solver. Nothing here imports
  ball_contacts or batched_world, nor calls world_spec.contact_response.

The arm: URDF loaded with its inertias, and the drives' rotor inertia (world_spec's armature, which the URDF
lacks and a real UR's joints have) as a rotor geared 1:1 to each joint, since Bullet's multibody has no
armature field. Every joint's motor gets the reference (q_ref, v_ref) from the actuator model each step and
solves joint velocity = v_ref + (Kp/Kd)(q_ref - q) (Bullet's positionGain (Kp/Kd) dt, velocityGain 1: the
corner frequency of world_spec's PD, 20 rad/s big joints, 25 wrists) with its torque capped at the URDF effort
(gravity included: Bullet has no separate compensation); joint speed capped at the URDF velocity limit
(maxJointVelocity). No link or joint damping. joint_drive='pd' instead applies world_spec's servo as joint
torques (PD clipped to the efforts, gravity from Bullet's inverse dynamics outside the clip): the MuJoCo
cell's servo law on Bullet's dynamics and contacts, a diagnostic.

The ball: 2.7 g, radius 20 mm, a thin shell (inertia 2/3 m r^2), air drag a = -k|v|v applied as an external
force before every step (Bullet has no aerodynamics), no Magnus force. Contacts (Bullet multiplies the two
bodies' coefficients: the ball has restitution 1 and friction 1, so a surface's own values are the pair's):
* restitution = world_spec's for the surface (table 0.89, blade 0.78, net 0.1, other links 0.6);
* Coulomb friction from world_spec's tangential factor f: a sliding ball loses mu (1 + e) |v_n| of its
  tangential speed, so mu = (1 - f) tan(a) / (1 + e) gives f at the reference impact ratio tan(a) =
  |v_t| / |v_n|: 1.67 for the table (the mean over evaluation seeds 1000-1009's first bounces), 0.5 for blade,
  net and links (guessed). Steeper impacts stick and roll (a shell then keeps 0.6 of its tangential speed,
  and spins), which the analytic law does not have;
* settings that keep Bullet's bounces honest (bullet3 issues on lossy and sticky bounces):
  restitutionVelocityThreshold 0 (restitution is not zeroed for slow impacts), contactERP 0 and frictionERP 0
  (Bullet's penetration recovery pushes the ball out with extra speed: a table bounce measured 0.90-0.96 for
  0.89, with or without split impulse; with 0 it is 0.89 at 1-6 m/s, from 0.5-4 mm above the table), split
  impulse with contactSlop 0, warmStartingFactor 0, contact processing threshold 0 (only touching contacts are
  solved), no rolling or spinning friction, no damping, static bodies in maximal coordinates, 1 ms steps.
  At 1 ms a ball at 15 m/s relative to the blade moves 15 mm per step, less than the 27.5 mm between the blade's
  mid-plane and the ball's centre at contact, so the discrete collision detection sees every touch; the ball also
  sweeps a sphere (ccdSweptSphereRadius) against fast static obstacles.
The referee reads Bullet's contact points after each step: a touch of a body (table, net, blade, another
robot link) that was not touched in the previous step is a contact event at the ball's centre; a robot link
touching the table or net is a robot-table contact.
"""

from __future__ import annotations

import math
import os
import tempfile
import xml.etree.ElementTree as ET
from dataclasses import dataclass

import numpy as np

from stylepong_sim.cells.quiet_stdout import quiet_c_stdout

with quiet_c_stdout():  # its import prints its build time on stdout, which a node's output should not carry
    import pybullet
    from pybullet_utils import bullet_client

from stylepong_description import robot_model
from stylepong_sim import world_spec
from stylepong_sim.cells import ur_servoj
from stylepong_sim.cells.cell_base import CellBase
from stylepong_sim.cells.cell_inputs import FRAME_TOOL, FRAME_WORLD, MAX_LAUNCH_SPEED_M_S, InputError  # noqa: F401

MOTOR_DRIVE, PD_DRIVE = 'motor', 'pd'
JOINT_DRIVES = (MOTOR_DRIVE, PD_DRIVE)
PADDLE_HANDLE_LINK = 'paddle_handle'  # the handle's collision split from the blade's (own restitution)
TABLE_TANGENT_OVER_NORMAL = 1.67  # mean |v_t|/|v_n| of the incoming balls at their first bounce
CONTACT_TANGENT_OVER_NORMAL = 0.5  # guessed for blade, net and links
BALL_SHELL_INERTIA_KG_M2 = 2.0 / 3.0 * world_spec.BALL_MASS_KG * world_spec.BALL_RADIUS_M**2
SOLVER_ITERATIONS = 50
# Bullet's solver as the analytic contacts need it: no restitution threshold, slop or error reduction that
# would bend a bounce, no warm start that would carry one contact's impulse into the next, and the same
# contact order on every run.
ENGINE_PARAMETERS = {
    'numSolverIterations': SOLVER_ITERATIONS,
    'restitutionVelocityThreshold': 0.0,
    'warmStartingFactor': 0.0,
    'useSplitImpulse': 1,
    'contactSlop': 0.0,
    'contactERP': 0.0,
    'frictionERP': 0.0,
    'enableConeFriction': 0,
    'deterministicOverlappingPairs': 1,
}
# Contact and motion with nothing the analytic models lack: no rolling or spinning friction, no damping,
# contacts from touching on (no processing margin).
FREE_CONTACT = {
    'rollingFriction': 0.0,
    'spinningFriction': 0.0,
    'linearDamping': 0.0,
    'angularDamping': 0.0,
    'contactProcessingThreshold': 0.0,
}
ROTORS_POSITION_M = [0.0, 0.0, -5.0]  # out of the way (the rotors collide with nothing anyway)
ROTOR_MASS_KG = 1.0  # on the rotor's axis: no gravity torque, only its inertia counts
GEAR_MAX_TORQUE_NM = 1.0e5  # a rigid gear: far above any joint's effort


def coulomb_friction(tangential_factor: float, restitution: float, tangent_over_normal: float) -> float:
    """The Coulomb coefficient with which a sliding ball keeps `tangential_factor` of its tangential speed
    at an impact of |v_t| / |v_n| = tangent_over_normal (impulse mu (1 + e) |v_n| against it)."""
    return (1.0 - tangential_factor) * tangent_over_normal / (1.0 + restitution)


@dataclass(frozen=True)
class SurfaceContact:
    """A surface's Bullet contact coefficients (the ball's are 1: the pair takes these)."""

    restitution: float
    friction: float


SURFACES = {
    'table': SurfaceContact(
        world_spec.TABLE_RESTITUTION,
        coulomb_friction(world_spec.TABLE_TANGENTIAL_FACTOR, world_spec.TABLE_RESTITUTION, TABLE_TANGENT_OVER_NORMAL),
    ),
    'net': SurfaceContact(
        world_spec.NET_RESTITUTION,
        coulomb_friction(world_spec.NET_TANGENTIAL_FACTOR, world_spec.NET_RESTITUTION, CONTACT_TANGENT_OVER_NORMAL),
    ),
    'blade': SurfaceContact(
        world_spec.PADDLE_RESTITUTION,
        coulomb_friction(
            world_spec.PADDLE_TANGENTIAL_FACTOR, world_spec.PADDLE_RESTITUTION, CONTACT_TANGENT_OVER_NORMAL
        ),
    ),
    'link': SurfaceContact(
        world_spec.ROBOT_LINK_RESTITUTION,
        coulomb_friction(
            world_spec.ROBOT_LINK_TANGENTIAL_FACTOR, world_spec.ROBOT_LINK_RESTITUTION, CONTACT_TANGENT_OVER_NORMAL
        ),
    ),
}


def bullet_urdf_xml() -> str:
    """The robot's URDF for Bullet: the one model, with mesh paths made absolute, the paddle's handle
    collision moved to a link of its own (so the blade and the handle have their own restitution) and
    the massless frames (paddle_centre, the handle link) given a zero inertial (Bullet gives 1 kg otherwise)."""
    share = str(robot_model.example_robot_data_dir())
    robot = ET.fromstring(robot_model.urdf_xml().replace(robot_model.MESH_PACKAGE_URI, share + '/'))
    for element in robot.findall('mujoco'):
        robot.remove(element)
    paddle = next(link for link in robot.findall('link') if link.get('name') == robot_model.PADDLE_BODY)
    handle = ET.SubElement(robot, 'link', name=PADDLE_HANDLE_LINK)
    for collision in paddle.findall('collision'):
        if collision.get('name') == 'paddle_handle':
            paddle.remove(collision)
            handle.append(collision)
    joint = ET.SubElement(robot, 'joint', name='paddle-paddle_handle_fixed_joint', type='fixed')
    ET.SubElement(joint, 'parent', link=robot_model.PADDLE_BODY)
    ET.SubElement(joint, 'child', link=PADDLE_HANDLE_LINK)
    ET.SubElement(joint, 'origin', xyz='0 0 0', rpy='0 0 0')
    for link in robot.findall('link'):
        if link.find('inertial') is None:
            inertial = ET.SubElement(link, 'inertial')
            ET.SubElement(inertial, 'mass', value='0')
            ET.SubElement(inertial, 'inertia', ixx='0', ixy='0', ixz='0', iyy='0', iyz='0', izz='0')
    return ET.tostring(robot, encoding='unicode')


def _quaternion_of(rotation: np.ndarray) -> tuple[float, float, float, float]:
    """Bullet's (x, y, z, w) of a rotation matrix (the base's yaw)."""
    yaw = math.atan2(rotation[1, 0], rotation[0, 0])
    return (0.0, 0.0, math.sin(yaw / 2.0), math.cos(yaw / 2.0))


class BulletCell(CellBase):
    """The cell in PyBullet: UR5 with paddle, table, net, floor and ball, with the referee watching."""

    def __init__(
        self,
        home_joint_positions_rad=world_spec.HOME_JOINT_POSITIONS_RAD,
        actuator: str = ur_servoj.IDEAL,
        servoj: ur_servoj.ServojSettings = ur_servoj.ServojSettings(),
        joint_drive: str = MOTOR_DRIVE,
    ):
        if joint_drive not in JOINT_DRIVES:
            raise ValueError(f'joint_drive must be one of {", ".join(JOINT_DRIVES)}, got {joint_drive!r}')
        self.joint_drive = joint_drive
        self._time_s = 0.0
        super().__init__(home_joint_positions_rad, actuator, world_spec.PHYSICS_DT_S)
        self._effort_nm = self._joint_limits.effort_nm.copy()
        self._reference = ur_servoj.make_reference(
            actuator, self.home_joint_positions_rad, self._joint_limits.velocity_rad_s, servoj
        )
        kp = np.array(world_spec.ARM_KP_NM_PER_RAD)
        kd = np.array(world_spec.ARM_KD_NMS_PER_RAD)
        self._position_gains = (kp / kd * self._dt).tolist()
        self._velocity_gains = [1.0] * robot_model.NUM_JOINTS
        self._forces = self._effort_nm.tolist()
        self._kp_nm_per_rad = kp
        self._kd_nms_per_rad = kd

        with quiet_c_stdout():  # connecting prints 'argv[0]=' on stdout
            self._p = bullet_client.BulletClient(connection_mode=pybullet.DIRECT)
        p = self._p
        p.setTimeStep(self._dt)
        p.setGravity(0.0, 0.0, -world_spec.GRAVITY_M_S2)
        p.setPhysicsEngineParameter(**ENGINE_PARAMETERS)
        half_thickness_m = world_spec.TABLE_THICKNESS_M / 2.0
        self._table = self._static_box(
            (0.0, 0.0, world_spec.TABLE_HEIGHT_M - half_thickness_m),
            (world_spec.HALF_LENGTH_M, world_spec.HALF_WIDTH_M, half_thickness_m),
            SURFACES['table'],
        )
        low, high = np.array(world_spec.NET_BOX_LOW_M), np.array(world_spec.NET_BOX_HIGH_M)
        self._net = self._static_box((low + high) / 2.0, (high - low) / 2.0, SURFACES['net'])
        self._floor = p.createMultiBody(0.0, p.createCollisionShape(pybullet.GEOM_PLANE), useMaximalCoordinates=True)
        self._robot, self._joints, self._links = self._load_robot()
        self._rotors = self._add_rotors()
        self._blade_link = self._links[robot_model.PADDLE_BODY]
        self._handle_link = self._links[PADDLE_HANDLE_LINK]
        self._tool_link = self._links[robot_model.TOOL_FRAME]
        self._centre_link = self._links[robot_model.PADDLE_CENTRE_FRAME]
        # The tool's subtree (what a wrist F/T sensor carries): tool0, paddle, handle, paddle_centre.
        self._tool_links = [
            self._links[n]
            for n in (
                robot_model.TOOL_FRAME,
                robot_model.PADDLE_BODY,
                PADDLE_HANDLE_LINK,
                robot_model.PADDLE_CENTRE_FRAME,
            )
        ]
        self._tool_mass_kg = sum(p.getDynamicsInfo(self._robot, link)[0] for link in self._tool_links)
        self._ball_shape = p.createCollisionShape(pybullet.GEOM_SPHERE, radius=world_spec.BALL_RADIUS_M)
        self._ball_body: int | None = None

        self._touching: set[str] = set()
        self._q = np.zeros(6)
        self._qd = np.zeros(6)
        self._tau = np.zeros(6)
        self._tau_pd = np.zeros(6)
        if joint_drive == PD_DRIVE:  # Bullet's default velocity motors off: the torques are all ours
            p.setJointMotorControlArray(self._robot, self._joints, pybullet.VELOCITY_CONTROL, forces=[0.0] * 6)
        self._tool_velocity_prev: tuple[np.ndarray, np.ndarray] | None = None
        self._tool_acceleration = (np.zeros(3), np.zeros(3))
        self._reset_robot()

    # --- construction ------------------------------------------------------------------------------
    def _static_box(self, centre_m, half_extents_m, surface: SurfaceContact) -> int:
        p = self._p
        shape = p.createCollisionShape(pybullet.GEOM_BOX, halfExtents=[float(v) for v in half_extents_m])
        # Static rigid bodies (maximal coordinates): their contacts with the ball are solved with split impulse.
        body = p.createMultiBody(0.0, shape, basePosition=[float(v) for v in centre_m], useMaximalCoordinates=True)
        p.changeDynamics(
            body,
            -1,
            restitution=surface.restitution,
            lateralFriction=surface.friction,
            rollingFriction=0.0,
            spinningFriction=0.0,
            contactProcessingThreshold=0.0,
        )
        return body

    def _load_robot(self) -> tuple[int, list[int], dict[str, int]]:
        p = self._p
        rotation, position = world_spec.robot_base_pose()
        with tempfile.TemporaryDirectory() as folder:
            path = os.path.join(folder, 'ur5_paddle.urdf')
            with open(path, 'w') as file:
                file.write(bullet_urdf_xml())
            robot = p.loadURDF(
                path,
                basePosition=position.tolist(),
                baseOrientation=_quaternion_of(rotation),
                useFixedBase=True,
                flags=pybullet.URDF_USE_INERTIA_FROM_FILE,
            )
        joints_by_name, links = {}, {}
        for index in range(p.getNumJoints(robot)):
            info = p.getJointInfo(robot, index)
            joints_by_name[info[1].decode()] = index
            links[info[12].decode()] = index
        joints = [joints_by_name[name] for name in robot_model.JOINT_NAMES]
        velocity = robot_model.joint_limits().velocity_rad_s
        for i, joint in enumerate(joints):
            p.changeDynamics(robot, joint, maxJointVelocity=float(velocity[i]), jointDamping=0.0)
        for link in [-1, *links.values()]:
            surface = SURFACES['blade'] if link == links[robot_model.PADDLE_BODY] else SURFACES['link']
            p.changeDynamics(
                robot,
                link,
                restitution=surface.restitution,
                lateralFriction=surface.friction,
                **FREE_CONTACT,
            )
        return robot, joints, links

    def _add_rotors(self) -> int:
        """The drives' rotor inertia (world_spec.ARM_ARMATURE_KG_M2), which a real UR's joints have and the URDF
        lacks: a fixed-base body of six free rotors, each geared 1:1 to its arm joint. Bullet's multibody has no
        armature; the gear constraints add it to the joint-space inertia exactly (M(q) + diag(armature)), solved
        with the motors, so a drive's effort accelerates its rotor too. The rotors have no collision shape."""
        p = self._p
        armature = [float(a) for a in world_spec.ARM_ARMATURE_KG_M2]
        identity = [0.0, 0.0, 0.0, 1.0]
        rotors = p.createMultiBody(
            baseMass=0.0,
            basePosition=ROTORS_POSITION_M,
            linkMasses=[ROTOR_MASS_KG] * 6,
            linkCollisionShapeIndices=[-1] * 6,
            linkVisualShapeIndices=[-1] * 6,
            linkPositions=[[0.0, 0.0, 0.0]] * 6,
            linkOrientations=[identity] * 6,
            linkInertialFramePositions=[[0.0, 0.0, 0.0]] * 6,
            linkInertialFrameOrientations=[identity] * 6,
            linkParentIndices=[0] * 6,
            linkJointTypes=[pybullet.JOINT_REVOLUTE] * 6,
            linkJointAxis=[[0.0, 0.0, 1.0]] * 6,
        )
        for rotor, (joint, inertia) in enumerate(zip(self._joints, armature)):
            p.changeDynamics(
                rotors,
                rotor,
                localInertiaDiagonal=[inertia] * 3,
                linearDamping=0.0,
                angularDamping=0.0,
                jointDamping=0.0,
            )
            gear = p.createConstraint(
                self._robot,
                joint,
                rotors,
                rotor,
                pybullet.JOINT_GEAR,
                [0.0, 0.0, 1.0],
                [0.0, 0.0, 0.0],
                [0.0, 0.0, 0.0],
            )
            # gearRatio -1: the rotor turns with its joint; erp 0: only velocities are tied (angles may drift apart).
            p.changeConstraint(gear, gearRatio=-1.0, maxForce=GEAR_MAX_TORQUE_NM, erp=0.0)
        p.setJointMotorControlArray(rotors, list(range(6)), pybullet.VELOCITY_CONTROL, forces=[0.0] * 6)
        return rotors

    # --- the engine's side of the commands (CellBase has the rest) ---------------------------------
    def _command_reference(self, q_rad: np.ndarray) -> None:
        self._reference.command(q_rad)

    def _start_ball(self) -> None:
        p = self._p
        body = p.createMultiBody(
            world_spec.BALL_MASS_KG, self._ball_shape, basePosition=self._ball_p.tolist(), useMaximalCoordinates=True
        )
        # mass again: on a maximal-coordinates body, changing the inertia alone zeroes the mass (PyBullet 3.2.7).
        p.changeDynamics(
            body,
            -1,
            mass=world_spec.BALL_MASS_KG,
            restitution=1.0,
            lateralFriction=1.0,
            **FREE_CONTACT,
            localInertiaDiagonal=[BALL_SHELL_INERTIA_KG_M2] * 3,
            ccdSweptSphereRadius=0.9 * world_spec.BALL_RADIUS_M,
        )
        p.resetBaseVelocity(body, self._ball_v.tolist(), [0.0, 0.0, 0.0])
        self._ball_body = body
        self._touching = set()

    def _drop_ball(self) -> None:
        self._p.removeBody(self._ball_body)
        self._ball_body = None

    # --- state -------------------------------------------------------------------------------------
    @property
    def time_s(self) -> float:
        return self._time_s

    @property
    def joint_positions_rad(self) -> np.ndarray:
        return self._q.copy()

    @property
    def joint_velocities_rad_s(self) -> np.ndarray:
        return self._qd.copy()

    @property
    def joint_efforts_nm(self) -> np.ndarray:
        """The joint motors' torques (gravity included)."""
        return self._tau.copy()

    def paddle_pose(self) -> tuple[np.ndarray, np.ndarray]:
        return self._link_pose(self._centre_link)

    def tool_pose(self) -> tuple[np.ndarray, np.ndarray]:
        return self._link_pose(self._tool_link)

    def tool_wrench(self, include_inertia: bool = False) -> tuple[np.ndarray, np.ndarray]:
        """The wrench the environment applies on the tool (weight, hand, contacts), tool0 axes, about tool0's
        origin; include_inertia: minus the tool's mass times its acceleration, as a physical sensor reads
        (the tool's rotational inertia is small and left out)."""
        origin, rotation = self.tool_pose()
        force = np.array([0.0, 0.0, -world_spec.GRAVITY_M_S2 * self._tool_mass_kg])
        torque = np.zeros(3)
        com = self._tool_centre_of_mass()
        torque += np.cross(com - origin, force)
        if self._hand is not None:
            hand_force, hand_torque = self._hand_in_world()
            force += hand_force
            torque += hand_torque
        for contact in self._p.getContactPoints(bodyA=self._robot):
            if contact[3] in self._tool_links:
                normal = np.array(contact[7])
                push = contact[9] * normal + contact[10] * np.array(contact[11]) + contact[12] * np.array(contact[13])
                force += push
                torque += np.cross(np.array(contact[5]) - origin, push)
        if include_inertia:
            inertial = -self._tool_mass_kg * self._tool_acceleration[0]
            force += inertial
            torque += np.cross(com - origin, inertial)
        return rotation.T @ force, rotation.T @ torque

    # --- internals ---------------------------------------------------------------------------------
    def _reset_robot(self) -> None:
        p = self._p
        for rotor, (joint, q) in enumerate(zip(self._joints, self.home_joint_positions_rad)):
            p.resetJointState(self._robot, joint, float(q), 0.0)
            p.resetJointState(self._rotors, rotor, float(q), 0.0)
        self._q_cmd = self.home_joint_positions_rad.copy()
        self._reference.reset(self.home_joint_positions_rad, self._time_s)
        self._tool_velocity_prev = None
        self._read_joints()

    def _read_joints(self) -> None:
        states = self._p.getJointStates(self._robot, self._joints)
        self._q = np.array([s[0] for s in states])
        self._qd = np.array([s[1] for s in states])
        self._tau = self._tau_pd if self.joint_drive == PD_DRIVE else np.array([s[3] for s in states])

    def _link_pose(self, link: int) -> tuple[np.ndarray, np.ndarray]:
        state = self._p.getLinkState(self._robot, link, computeForwardKinematics=True)
        rotation = np.array(self._p.getMatrixFromQuaternion(state[5])).reshape(3, 3)
        return np.array(state[4]), rotation

    def _tool_centre_of_mass(self) -> np.ndarray:
        state = self._p.getLinkState(self._robot, self._blade_link, computeForwardKinematics=True)
        return np.array(state[0])  # the paddle link carries the tool's mass (tool0 and the frames have none)

    def _push_on_tool(self, force_n: np.ndarray, torque_nm: np.ndarray) -> None:
        origin, _ = self.tool_pose()
        p = self._p
        p.applyExternalForce(self._robot, self._tool_link, force_n.tolist(), origin.tolist(), pybullet.WORLD_FRAME)
        p.applyExternalTorque(self._robot, self._tool_link, torque_nm.tolist(), pybullet.WORLD_FRAME)

    def _step_once(self) -> None:
        p = self._p
        q_ref, v_ref = self._reference.step(self._time_s + self._dt, self._dt)
        if self.joint_drive == PD_DRIVE:
            self._apply_pd_torques(q_ref, v_ref)
        else:
            p.setJointMotorControlArray(
                self._robot,
                self._joints,
                pybullet.POSITION_CONTROL,
                targetPositions=q_ref.tolist(),
                targetVelocities=v_ref.tolist(),
                positionGains=self._position_gains,
                velocityGains=self._velocity_gains,
                forces=self._forces,
            )
        if self._hand is not None:
            self._apply_hand_wrench()
        if self._ball_body is not None:
            drag = world_spec.BALL_MASS_KG * world_spec.drag_acceleration(self._ball_v)
            p.applyExternalForce(self._ball_body, -1, drag.tolist(), self._ball_p.tolist(), pybullet.WORLD_FRAME)
        p.stepSimulation()
        self._time_s += self._dt
        self._read_joints()
        self._track_tool_acceleration()
        if self._referee.rally_open:
            self._check_robot_table_contacts()
        if self._ball_body is not None:
            self._watch_ball()

    def _apply_pd_torques(self, q_ref: np.ndarray, v_ref: np.ndarray) -> None:
        """joint_drive 'pd': world_spec's servo as joint torques on Bullet's dynamics (PD clipped to the efforts,
        gravity compensation from Bullet's inverse dynamics outside the clip, as world_spec states the law)."""
        pd = self._kp_nm_per_rad * (q_ref - self._q) + self._kd_nms_per_rad * (v_ref - self._qd)
        zeros = [0.0] * robot_model.NUM_JOINTS
        gravity = np.array(self._p.calculateInverseDynamics(self._robot, self._q.tolist(), zeros, zeros))
        self._tau_pd = np.clip(pd, -self._effort_nm, self._effort_nm) + gravity
        self._p.setJointMotorControlArray(
            self._robot, self._joints, pybullet.TORQUE_CONTROL, forces=self._tau_pd.tolist()
        )

    def _track_tool_acceleration(self) -> None:
        state = self._p.getLinkState(self._robot, self._blade_link, computeLinkVelocity=True)
        velocity = (np.array(state[6]), np.array(state[7]))
        if self._tool_velocity_prev is not None:
            self._tool_acceleration = (
                (velocity[0] - self._tool_velocity_prev[0]) / self._dt,
                (velocity[1] - self._tool_velocity_prev[1]) / self._dt,
            )
        self._tool_velocity_prev = velocity

    def _check_robot_table_contacts(self) -> None:
        for obstacle in (self._table, self._net):
            # Bullet also lists points of its contact manifold that are still apart (distance up to its
            # breaking threshold, 2 cm): only a point pushing the bodies apart is a touch, as for the ball.
            touching = [c for c in self._p.getContactPoints(bodyA=self._robot, bodyB=obstacle) if c[9] > 0.0]
            if touching:
                self._events += self._referee.robot_table_contact(self._time_s, touching[0][6])
                return

    def _contact_kind(self, body: int, link: int) -> str | None:
        if body == self._table:
            return 'table'
        if body == self._net:
            return 'net'
        if body == self._robot:
            return 'blade' if link == self._blade_link else 'link'
        return None  # the floor: the referee sees a dead ball by its position

    def _watch_ball(self) -> None:
        p = self._p
        position, _ = p.getBasePositionAndOrientation(self._ball_body)
        velocity, _ = p.getBaseVelocity(self._ball_body)
        self._ball_p, self._ball_v = np.array(position), np.array(velocity)
        touching = set()
        for contact in p.getContactPoints(bodyA=self._ball_body):
            kind = self._contact_kind(contact[2], contact[4])
            if kind is not None and contact[9] > 0.0:
                touching.add(kind)
        time_s = self._time_s
        report = {
            'table': self._referee.table_contact,
            'net': self._referee.net_contact,
            'blade': self._referee.paddle_contact,
            'link': self._referee.robot_contact,
        }
        for kind in ('table', 'net', 'blade', 'link'):  # new touches only: a ball resting on a body is one touch
            if kind in touching and kind not in self._touching:
                self._events += report[kind](time_s, self._ball_p)
        self._touching = touching
        self._judge_ball(time_s)

    def close(self) -> None:
        """Disconnect from Bullet (the cell is unusable afterwards)."""
        if self._p is not None:
            self._p.disconnect()
            self._p = None
