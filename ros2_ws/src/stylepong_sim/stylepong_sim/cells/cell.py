"""The simulated UR5 table-tennis cell: MuJoCo robot + analytic ball + referee, free of ROS.

API (all units SI; joint vectors have 6 entries in URDF order, stylepong_description.robot_model.JOINT_NAMES)
    cell = Cell()                               robot at home and at rest, no ball, time 0
    Cell(actuator='ur_servoj', servoj=ur_servoj.ServojSettings(125.0, 0.03, 2000.0))   the UR's servoj instead
    cell.reset()                                robot to home at rest, targets home, ball removed (its rally
                                                ends 'aborted'), hand released; time keeps running
    cell.set_joint_targets(q_rad)               position targets for the servo; InputError (a ValueError) if
                                                the vector has the wrong length, NaN/inf or leaves the URDF
                                                limits (then the previous target stays)
    cell.set_hand_wrench(force_n, torque_nm, frame='world'|'tool0', duration_s=inf)
                                                a hand on the tool: force and torque act at tool0's origin,
                                                components in `frame` axes (tool0: rotating with the tool);
                                                released after duration_s of sim time
    cell.clear_hand_wrench()
    ball_id = cell.launch_ball(position_m, velocity_m_s)   a ball (ValueError if not finite, faster than
                                                MAX_LAUNCH_SPEED_M_S or outside the cell); replaces any ball
    cell.remove_ball()
    cell.step(n_steps=1) / cell.step_for(duration_s)        advance physics in steps of world_spec.PHYSICS_DT_S
    cell.time_s, cell.joint_positions_rad, cell.joint_velocities_rad_s, cell.joint_efforts_nm,
    cell.joint_targets_rad
    cell.tool_wrench(include_inertia=False) -> (force_n, torque_nm)
                                                what a wrist F/T sensor between wrist_3 and the tool reads, in
                                                tool0 axes about tool0's origin: the wrench the environment applies
                                                on the tool (its weight, the hand, contacts on tool or paddle).
                                                include_inertia=True: the physical sensor's reading, which also
                                                carries the tool's own inertia (minus its mass times acceleration);
                                                both agree when the tool is at rest
    cell.ball_in_play, cell.ball_id, cell.ball_position_m, cell.ball_velocity_m_s  (None without a ball)
    cell.pop_events() -> list[referee.RallyEvent]           events since the last call, in order
    cell.paddle_pose(), cell.tool_pose() -> (position_m, rotation 3x3: columns = frame axes in world)
    cell.model, cell.data                       the MuJoCo objects (read them, e.g. to render; do not step them)
The engine-free half of this API (input checks, ball launch and removal, hand wrench timing, events, getters) is
cell_base.CellBase, which the PyBullet cell derives from too; this module is MuJoCo's half.

Robot: the URDF's arm under the servo law of world_spec (actuator 'ideal': rate-limited reference; 'ur_servoj':
the UR controller's servoj shapes the reference instead, ur_servoj.py; then PD with torques clipped to
the effort limits, ideal gravity compensation, armature, joint speed clip). It collides with the table,
net and floor (MuJoCo contacts), never with itself. Joint efforts = servo torque + gravity compensation.

Ball (2.7 g, no spin): integrated here, not by MuJoCo, every physics step dt (the batched world integrates the
same forces by the midpoint rule at its coarser step):
    v' = v + (g + drag_acceleration(v)) dt,  p' = p + v' dt                 (semi-implicit Euler)
  then the earliest contact within the step is found on the straight segment p -> p' (for the blade, the
  segment in the blade's moving frame): table, net and blade by ball_contacts (exact crossing times of
  the table top and of the net's and blade's faces; the end position against the net's top and ends and
  the blade's rim); the other robot links, only when none of those is touched, by the ball's end
  position against their collision meshes (MuJoCo's distance query).
  At a contact at fraction f of the step, with outward unit normal n and the surface's velocity u at the
  contact point:  v_out = u + world_spec.contact_response(v' - u, n, restitution, tangential_factor);
  the ball is put on the surface and flies the rest of the step, p' = p_contact + v_out (1 - f) dt.
  One contact per step. Coefficients: table TABLE_*, net NET_*, blade PADDLE_*, other links ROBOT_LINK_*.
  The ball never loads the robot (its impulse is negligible next to the servo) and is seen by nothing but
  this code; the MuJoCo ball is a mocap marker for rendering and distance queries.
  The ball is removed when dead (floor, left the cell: referee.ball_is_dead) after its verdict, or
  BALL_LIFETIME_S after its launch.
The referee (referee.py) is told every contact and the ball's state after every step.
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np

from stylepong_description import robot_model
from stylepong_sim import world_spec
from stylepong_sim.cells import ball_contacts, scene, ur_servoj
from stylepong_sim.cells.cell_base import CellBase
from stylepong_sim.cells.cell_inputs import FRAME_TOOL, FRAME_WORLD, MAX_LAUNCH_SPEED_M_S, InputError  # noqa: F401

_GRAVITY = np.array([0.0, 0.0, -world_spec.GRAVITY_M_S2])


@dataclass(frozen=True)
class BallPhysics:
    """Contact and air coefficients of the ball (world_spec's nominal values; vary them to randomise)."""

    drag_k_per_m: float = world_spec.DRAG_K_PER_M
    table_restitution: float = world_spec.TABLE_RESTITUTION
    table_tangential_factor: float = world_spec.TABLE_TANGENTIAL_FACTOR
    paddle_restitution: float = world_spec.PADDLE_RESTITUTION
    paddle_tangential_factor: float = world_spec.PADDLE_TANGENTIAL_FACTOR
    net_restitution: float = world_spec.NET_RESTITUTION
    net_tangential_factor: float = world_spec.NET_TANGENTIAL_FACTOR
    robot_restitution: float = world_spec.ROBOT_LINK_RESTITUTION
    robot_tangential_factor: float = world_spec.ROBOT_LINK_TANGENTIAL_FACTOR


class Cell(CellBase):
    """The simulated cell: UR5 with paddle, table, net and ball in MuJoCo, with the referee watching."""

    def __init__(
        self,
        home_joint_positions_rad=world_spec.HOME_JOINT_POSITIONS_RAD,
        ball_physics: BallPhysics = BallPhysics(),
        actuator: str = ur_servoj.IDEAL,
        servoj: ur_servoj.ServojSettings = ur_servoj.ServojSettings(),
    ):
        self.model = scene.build_model()
        self.data = mujoco.MjData(self.model)
        super().__init__(home_joint_positions_rad, actuator, self.model.opt.timestep)
        self.ball_physics = ball_physics
        m = self.model
        self._v_max_rad_s = self._joint_limits.velocity_rad_s.copy()
        self._ref_step_rad = self._v_max_rad_s * self._dt
        self._kd_over_kp_s = np.array(world_spec.ARM_KD_NMS_PER_RAD) / np.array(world_spec.ARM_KP_NM_PER_RAD)

        qadr = np.array([m.jnt_qposadr[m.joint(n).id] for n in robot_model.JOINT_NAMES])
        dofadr = np.array([m.jnt_dofadr[m.joint(n).id] for n in robot_model.JOINT_NAMES])
        if not (np.array_equal(qadr, np.arange(6)) and np.array_equal(dofadr, np.arange(6))):
            raise RuntimeError('the cell expects the arm joints first in qpos/qvel')
        self._tool_body = m.body(robot_model.TOOL_FRAME).id
        self._paddle_centre_body = m.body(robot_model.PADDLE_CENTRE_FRAME).id
        self._ball_mocap = m.body_mocapid[m.body(scene.BALL_BODY).id]
        self._ball_geom = m.geom('ball').id
        self._table_geom = m.geom('table_top').id
        self._net_geom = m.geom('net').id
        robot_bodies = {b for b in range(m.nbody) if self._is_robot_body(b)}
        self._robot_geom_mask = np.array([m.geom_bodyid[g] in robot_bodies for g in range(m.ngeom)])
        # Links the ball may touch besides the blade (handle, wrist, arm); ee_link's tiny marker box excluded.
        blade_geom = m.geom('paddle_blade').id
        self._link_geoms = np.array(
            [g for g in range(m.ngeom) if self._robot_geom_mask[g] and g != blade_geom and m.geom_size[g].max() > 0.006]
        )
        # A link's geom can touch the ball only if the ball centre is within its bounding sphere + radius.
        self._link_reach_sq_m2 = (m.geom_rbound[self._link_geoms] + world_spec.BALL_RADIUS_M) ** 2
        self._tool_subtree = np.array([b for b in range(m.nbody) if self._is_in_subtree(b, self._tool_body)])
        self._tree_root = m.body_rootid[self._tool_body]
        self._tool_weight_n = np.array([0.0, 0.0, -world_spec.GRAVITY_M_S2 * m.body_subtreemass[self._tool_body]])
        force_adr = m.sensor_adr[m.sensor(scene.FT_FORCE_SENSOR).id]
        torque_adr = m.sensor_adr[m.sensor(scene.FT_TORQUE_SENSOR).id]
        self._force_slice = slice(force_adr, force_adr + 3)
        self._torque_slice = slice(torque_adr, torque_adr + 3)
        self._jac = np.zeros((3, m.nv))
        self._abs_qvel = np.zeros(6)
        self._distance_fromto = np.zeros(6)

        self._paddle_prev: tuple[np.ndarray, np.ndarray] | None = None
        self._q_ref = self.home_joint_positions_rad.copy()
        self._ref_moving = False
        self._feedforward_active = False
        # actuator 'ur_servoj': the UR controller's servoj shapes the reference (ur_servoj.py); 'ideal' keeps
        # world_spec's reference below, which the batched world shares.
        self._servoj = (
            ur_servoj.ServojReference(self.home_joint_positions_rad, servoj)
            if actuator == ur_servoj.UR_SERVOJ
            else None
        )
        self._reset_robot()

    # --- the engine's side of the commands (CellBase has the rest) -------------------------------
    def clear_hand_wrench(self) -> None:
        super().clear_hand_wrench()
        self.data.xfrc_applied[self._tool_body] = 0.0

    def _command_reference(self, q_rad: np.ndarray) -> None:
        if self._servoj is not None:
            self._servoj.command(q_rad)
        self._ref_moving = not np.array_equal(q_rad, self._q_ref)

    def _start_ball(self) -> None:
        mujoco.mj_kinematics(self.model, self.data)
        self._paddle_prev = self.paddle_pose()
        self._place_ball_marker()

    def _drop_ball(self) -> None:
        self.data.mocap_pos[self._ball_mocap] = scene.BALL_PARKING_POSITION_M

    # --- state -----------------------------------------------------------------------------------
    @property
    def time_s(self) -> float:
        return float(self.data.time)

    @property
    def joint_positions_rad(self) -> np.ndarray:
        return self.data.qpos[:6].copy()

    @property
    def joint_velocities_rad_s(self) -> np.ndarray:
        return self.data.qvel[:6].copy()

    @property
    def joint_efforts_nm(self) -> np.ndarray:
        return self.data.qfrc_actuator[:6] + self.data.qfrc_gravcomp[:6]

    def tool_wrench(self, include_inertia: bool = False) -> tuple[np.ndarray, np.ndarray]:
        d = self.data
        if include_inertia:
            # MuJoCo's force/torque sensors give what the parent (wrist_3) exerts on the tool's subtree; the
            # sensor reads its opposite: environment's wrench minus the subtree's inertial wrench.
            return -d.sensordata[self._force_slice], -d.sensordata[self._torque_slice]
        # Weight of the subtree at its centre of mass, plus the external forces MuJoCo collected on its
        # bodies (contacts and xfrc_applied, i.e. the hand): spatial forces at the tree's centre of mass.
        tool = self._tool_body
        origin, rotation = d.xpos[tool], d.xmat[tool].reshape(3, 3)
        weight = self._tool_weight_n
        external = d.cfrc_ext[self._tool_subtree].sum(axis=0)
        force = weight + external[3:]
        torque = (
            np.cross(d.subtree_com[tool] - origin, weight)
            + external[:3]
            + np.cross(d.subtree_com[self._tree_root] - origin, external[3:])
        )
        return rotation.T @ force, rotation.T @ torque

    def paddle_pose(self) -> tuple[np.ndarray, np.ndarray]:
        return self._body_pose(self._paddle_centre_body)

    def tool_pose(self) -> tuple[np.ndarray, np.ndarray]:
        return self._body_pose(self._tool_body)

    # --- internals: robot ------------------------------------------------------------------------
    def _is_in_subtree(self, body: int, root: int) -> bool:
        while body != 0:
            if body == root:
                return True
            body = self.model.body_parentid[body]
        return False

    def _is_robot_body(self, body: int) -> bool:
        return self._is_in_subtree(body, self.model.body(robot_model.BASE_FRAME).id)

    def _reset_robot(self) -> None:
        d = self.data
        d.qpos[:6] = self.home_joint_positions_rad
        d.qvel[:6] = 0.0
        d.qacc_warmstart[:] = 0.0
        self._q_cmd = self.home_joint_positions_rad.copy()
        self._q_ref = self.home_joint_positions_rad.copy()
        self._ref_moving = False
        self._feedforward_active = False
        if self._servoj is not None:
            self._servoj.reset(self.home_joint_positions_rad, float(d.time))
        d.ctrl[:6] = self._q_ref
        mujoco.mj_forward(self.model, d)

    def _advance_servo_reference(self) -> None:
        """Move q_ref towards the command at most v_max dt; ctrl carries the velocity feed-forward."""
        delta = self._q_cmd - self._q_ref
        if np.all(np.abs(delta) <= self._ref_step_rad):
            step = delta
            self._q_ref = self._q_cmd.copy()
            self._ref_moving = False
        else:
            step = np.clip(delta, -self._ref_step_rad, self._ref_step_rad)
            self._q_ref = self._q_ref + step
        self.data.ctrl[:6] = self._q_ref + self._kd_over_kp_s * (step / self._dt)
        self._feedforward_active = True

    def _push_on_tool(self, force_n: np.ndarray, torque_nm: np.ndarray) -> None:
        d = self.data
        # xfrc_applied acts at the body's centre of mass; the hand acts at tool0's origin.
        lever = d.xpos[self._tool_body] - d.xipos[self._tool_body]
        d.xfrc_applied[self._tool_body, :3] = force_n
        d.xfrc_applied[self._tool_body, 3:] = torque_nm + np.cross(lever, force_n)

    def _step_once(self) -> None:
        m, d = self.model, self.data
        if self._servoj is not None:
            q_ref, v_ref = self._servoj.step(float(d.time) + self._dt, self._dt)
            d.ctrl[:6] = q_ref + self._kd_over_kp_s * v_ref
        elif self._ref_moving:
            self._advance_servo_reference()
        elif self._feedforward_active:
            d.ctrl[:6] = self._q_ref  # the reference has arrived: no more velocity feed-forward
            self._feedforward_active = False
        if self._hand is not None:
            self._apply_hand_wrench()
        mujoco.mj_step(m, d)
        qvel = d.qvel[:6]
        if (np.abs(qvel, out=self._abs_qvel) > self._v_max_rad_s).any():
            np.clip(qvel, -self._v_max_rad_s, self._v_max_rad_s, out=qvel)
        if d.ncon:
            self._check_robot_table_contacts()
        if self.ball_id is not None:
            mujoco.mj_kinematics(m, d)  # poses at the new time, for the ball's contacts
            self._step_ball()

    def _check_robot_table_contacts(self) -> None:
        if not self._referee.rally_open:
            return
        contacts = self.data.contact
        for i in range(self.data.ncon):
            g1, g2 = contacts.geom[i]
            env = g2 if self._robot_geom_mask[g1] else g1
            if env in (self._table_geom, self._net_geom) and self._robot_geom_mask[g1] != self._robot_geom_mask[g2]:
                self._events += self._referee.robot_table_contact(self.time_s, contacts.pos[i])
                return

    def _body_pose(self, body: int) -> tuple[np.ndarray, np.ndarray]:
        return self.data.xpos[body].copy(), self.data.xmat[body].reshape(3, 3).copy()

    def _point_velocity(self, point_m: np.ndarray, body: int) -> np.ndarray:
        mujoco.mj_comPos(self.model, self.data)  # mj_jac needs the motion subspaces at the new poses
        mujoco.mj_jac(self.model, self.data, self._jac, None, point_m, body)
        return self._jac @ self.data.qvel

    # --- internals: ball -------------------------------------------------------------------------
    def _place_ball_marker(self) -> None:
        self.data.mocap_pos[self._ball_mocap] = self._ball_p
        self.data.geom_xpos[self._ball_geom] = self._ball_p  # for distance queries before the next step

    def _step_ball(self) -> None:
        dt = self._dt
        physics = self.ball_physics
        p0, v0 = self._ball_p, self._ball_v
        v1 = v0 + (_GRAVITY + world_spec.drag_acceleration(v0, physics.drag_k_per_m)) * dt
        p1 = p0 + v1 * dt
        paddle_now = self.paddle_pose()
        contact = self._earliest_contact(p0, p1, v1, self._paddle_prev, paddle_now)
        self._paddle_prev = paddle_now
        time_s = self.time_s
        if contact is not None:
            restitution, tangential = {
                ball_contacts.TABLE: (physics.table_restitution, physics.table_tangential_factor),
                ball_contacts.NET: (physics.net_restitution, physics.net_tangential_factor),
                ball_contacts.PADDLE: (physics.paddle_restitution, physics.paddle_tangential_factor),
                ball_contacts.ROBOT: (physics.robot_restitution, physics.robot_tangential_factor),
            }[contact.kind]
            u = contact.surface_velocity_m_s
            v1 = u + world_spec.contact_response(v1 - u, contact.normal, restitution, tangential)
            p1 = contact.centre_m + v1 * ((1.0 - contact.fraction) * dt)
            contact_time_s = time_s - (1.0 - contact.fraction) * dt
            report = {
                ball_contacts.TABLE: self._referee.table_contact,
                ball_contacts.NET: self._referee.net_contact,
                ball_contacts.PADDLE: self._referee.paddle_contact,
                ball_contacts.ROBOT: self._referee.robot_contact,
            }[contact.kind]
            self._events += report(contact_time_s, contact.centre_m)
        self._ball_p, self._ball_v = p1, v1
        self._place_ball_marker()
        self._judge_ball(time_s)

    def _earliest_contact(self, p0, p1, v1, paddle_before, paddle_after) -> ball_contacts.Contact | None:
        """Table, net and blade (ball_contacts); the other robot links only when none of them is touched."""
        contact = ball_contacts.earliest_contact(p0, p1, v1, paddle_before, paddle_after, self._blade_point_velocity)
        return contact if contact is not None else self._robot_link_contact(p1, v1)

    def _blade_point_velocity(self, point_m: np.ndarray) -> np.ndarray:
        return self._point_velocity(point_m, self._paddle_centre_body)

    def _robot_link_contact(self, p1, v1) -> ball_contacts.Contact | None:
        """The ball's end position against the other robot links' collision meshes (MuJoCo's distance)."""
        d = self.data
        offsets = d.geom_xpos[self._link_geoms] - p1
        near = self._link_geoms[np.einsum('ij,ij->i', offsets, offsets) < self._link_reach_sq_m2]
        if near.size == 0:
            return None
        d.geom_xpos[self._ball_geom] = p1
        for geom in near:
            distance = mujoco.mj_geomDistance(self.model, d, self._ball_geom, int(geom), 0.01, self._distance_fromto)
            if distance > 0.0:
                continue
            surface_point = self._distance_fromto[3:6].copy()
            offset = p1 - surface_point
            normal = offset / max(float(np.linalg.norm(offset)), 1e-9)
            u = self._point_velocity(surface_point, int(self.model.geom_bodyid[geom]))
            if np.dot(v1 - u, normal) >= 0.0:
                continue
            centre = surface_point + normal * world_spec.BALL_RADIUS_M
            return ball_contacts.Contact(ball_contacts.ROBOT, 1.0, centre, normal, u)
        return None
