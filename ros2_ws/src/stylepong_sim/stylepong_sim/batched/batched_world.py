"""The batched table-tennis world: N copies of the cell stepped together in torch (cpu or cuda).

Why it lives here (docs/DESIGN.md, "A second simulator for training"): stylepong_sim holds everything
that simulates the cell (world spec, MuJoCo cell, referee) and stylepong_policy everything that learns
(spec, task rewards, PPO). This module is a second simulator of the same cell, held to the MuJoCo
cell by agreement tests, so it sits beside the cell and reads the same world spec, robot model and
referee rules; the task (rewards, goals, domain randomisation, observations) that turns it into an
RL environment is stylepong_policy.training.task.

What it simulates, for every environment at once (layout: the environment axis last, see
batched_kinematics):
* the UR5 + paddle under the cell's servo law (world_spec "Arm servo": rate-limited reference,
  PD clipped to the URDF efforts, ideal gravity compensation, armature, joint speed clip), integrated
  with the joint-space inertia and Coriolis torques of the one robot model (batched CRBA / RNEA);
* the ball: gravity and drag, and the cell's analytic contacts (world_spec.contact_response) with the
  table top, the net's faces and top, and the paddle's blade (faces swept in the blade's moving
  frame, so nothing tunnels; rim by the end position), one contact per step at its exact fraction;
* the referee's rules, the same functions of stylepong_sim.referee the cell's referee applies, on tensors:
  own bounces, hits, verdict and reason.
The cell steps physics at 1 ms; here physics runs at `physics_rate_hz` (default 120 Hz, two steps per
60 Hz policy step) with the ball integrated by the midpoint rule (exact for gravity, so the coarser
step loses nothing: landing points agree with the cell's to millimetres) and the arm at
`arm_substeps` finer steps per physics step (480 Hz), with the inertia and bias torques updated once per
policy step (`dynamics_every`). Joint trajectories agree with the cell's within 2 % RMS, the ball's
table contacts within 6 mm and its floor landings within 7 mm (test_batched_world_agreement); the
compiled world (`compile=True`) steps the same states as the eager one to float32 rounding
(test_batched_world_compiled). Robot-link contacts use capsules fitted to the links'
collision meshes (the cell queries the meshes themselves).
"""

from __future__ import annotations

import contextlib
import math
from dataclasses import dataclass, fields
from typing import NamedTuple

import torch

from stylepong_description import robot_model
from stylepong_sim import referee, world_spec
from stylepong_sim.batched import batched_kinematics
from stylepong_sim.batched.batched_kinematics import Kinematics

# The world's default step rates (the task's TaskConfig takes them from here): physics at 120 Hz, two
# steps per 60 Hz policy step, and the arm at 4 sub-steps per physics step (480 Hz); see the docstring.
PHYSICS_RATE_HZ = 120.0
ARM_SUBSTEPS = 4

# Contact kinds of one physics step.
_NONE, _TABLE, _NET, _PADDLE = 0, 1, 2, 3
# Contact fraction of a surface not touched in a step: past the step's end (1), so any real contact is earlier.
_NO_CONTACT = 2.0


class _Contact(NamedTuple):
    """The ball's contact in one physics step, per environment: which surface, when and where."""

    kind: torch.Tensor  # long [N]: _NONE, _TABLE, _NET or _PADDLE
    fraction: torch.Tensor  # [N] of the step at which it happens (1 where none)
    robot_link: torch.Tensor  # bool [N]: a robot link other than the blade, where nothing else was
    centre_m: torch.Tensor  # [3, N] ball centre at the contact, on the surface
    normal: torch.Tensor  # [3, N] unit, out of the surface towards the ball
    surface_velocity_m_s: torch.Tensor  # [3, N] the blade's velocity at the contact (0: table, net, none)


@contextlib.contextmanager
def torch_threads(threads: int | None):
    """Run the enclosed torch work with `threads` intra-op CPU threads (None: leave them as they are).

    The world is hundreds of small operations per step; with two threads each of them is a parallel
    region that waits for both, and on a loaded 2-core machine that made a step 6-11x slower (measured:
    159 vs 14 ms at N = 256, 788 vs 111 ms at N = 4096). Networks, big matrix products, keep theirs.
    """
    previous = torch.get_num_threads()
    if threads is None or threads == previous:
        yield
        return
    torch.set_num_threads(threads)
    try:
        yield
    finally:
        torch.set_num_threads(previous)


@dataclass
class PhysicsParams:
    """Per-environment physical parameters ([N] tensors; [6, N] for the servo gains).

    Defaults are the world spec's nominal values; the task randomises them (domain randomisation).
    """

    gravity_m_s2: torch.Tensor
    drag_k_per_m: torch.Tensor
    table_restitution: torch.Tensor
    table_tangential_factor: torch.Tensor
    paddle_restitution: torch.Tensor
    paddle_tangential_factor: torch.Tensor
    kp_nm_per_rad: torch.Tensor
    kd_nms_per_rad: torch.Tensor
    # Share of the joint drive that is a stiff velocity motor instead of world_spec's PD, in [0, 1] (0: the
    # cell's law). The motor reaches joint velocity v_ref + (Kp / Kd)(q_ref - q) within each sub-step, torque
    # permitting: Bullet's joint motors, and a UR's own joint controllers, which track servoj's setpoint
    # without the PD's lag. `evaluate --velocity-drive` sets it; the task can draw it (the recipe does not).
    velocity_drive: torch.Tensor
    # Reflected rotor inertia per joint [6, N]: a UR's harmonic drives have it, the URDF does not.
    armature_kg_m2: torch.Tensor

    @staticmethod
    def nominal(
        num_envs: int, device: torch.device | str = 'cpu', dtype: torch.dtype = torch.float32
    ) -> 'PhysicsParams':
        def full(value: float) -> torch.Tensor:
            return torch.full((num_envs,), float(value), device=device, dtype=dtype)

        def per_joint(values) -> torch.Tensor:
            return torch.tensor(values, device=device, dtype=dtype)[:, None].repeat(1, num_envs)

        return PhysicsParams(
            gravity_m_s2=full(world_spec.GRAVITY_M_S2),
            drag_k_per_m=full(world_spec.DRAG_K_PER_M),
            table_restitution=full(world_spec.TABLE_RESTITUTION),
            table_tangential_factor=full(world_spec.TABLE_TANGENTIAL_FACTOR),
            paddle_restitution=full(world_spec.PADDLE_RESTITUTION),
            paddle_tangential_factor=full(world_spec.PADDLE_TANGENTIAL_FACTOR),
            kp_nm_per_rad=per_joint(world_spec.ARM_KP_NM_PER_RAD),
            kd_nms_per_rad=per_joint(world_spec.ARM_KD_NMS_PER_RAD),
            velocity_drive=full(0.0),
            armature_kg_m2=per_joint(world_spec.ARM_ARMATURE_KG_M2),
        )

    def assign(self, env_ids: torch.Tensor, other: 'PhysicsParams') -> None:
        """Copy `other`'s values (for len(env_ids) environments) into these environments."""
        for f in fields(self):
            getattr(self, f.name)[..., env_ids] = getattr(other, f.name)


class ArmDynamics(NamedTuple):
    """The arm's joint-space dynamics at one state, held over a policy step's sub-steps ([6, 6, N], [6, N])."""

    inertia: torch.Tensor  # M(q) + armature
    inverse: torch.Tensor  # its inverse
    coriolis: torch.Tensor  # C(q, qd) qd
    gravity: torch.Tensor | None  # g(q); None in a world without velocity_drive (the PD's is compensated)


@dataclass
class StepEvents:
    """What happened during one `BatchedWorld.step` (one policy period), per environment [N]."""

    paddle_hit: torch.Tensor  # bool: the paddle touched the ball
    own_bounce: torch.Tensor  # bool: the ball bounced on the robot's half
    decided: torch.Tensor  # bool: the rally got its verdict in this period
    success: torch.Tensor  # bool: the verdict (valid where decided)
    reason: torch.Tensor  # long: index into referee.REASONS (valid where decided)


class BatchedWorld:
    """N table-tennis cells. Construct, `reset_envs` each environment with a ball, then `step` at the policy rate.

    State tensors (environment axis last): q_rad, qd_rad_s, q_ref_rad, q_cmd_rad [6, N]; ball_pos_m,
    ball_vel_m_s [3, N]; paddle_pos_m [3, N] and paddle_rot [3, 3, N] (blade centre; z = face normal);
    time_s [N] since the launch; referee state hit, own_bounces, open (no verdict yet), success, reason;
    landing_xy_m [2, N]: where a returned ball first touched the table (out balls: where the referee
    called them out), valid once decided after a hit; table_contact_pos_m [3, N]: the ball centre at
    its latest table contact.
    """

    def __init__(
        self,
        num_envs: int,
        device: str | torch.device = 'cpu',
        dtype: torch.dtype = torch.float32,
        policy_rate_hz: float = world_spec.POLICY_RATE_HZ,
        physics_rate_hz: float = PHYSICS_RATE_HZ,
        arm_substeps: int = ARM_SUBSTEPS,
        timeout_s: float = world_spec.BALL_TIMEOUT_S,
        dynamics_every: int | None = None,
        cpu_threads: int | None = 1,
        compile: bool = False,
        velocity_drive: bool = False,
    ):
        if num_envs < 1:
            raise ValueError('num_envs must be positive')
        steps = physics_rate_hz / policy_rate_hz
        if abs(steps - round(steps)) > 1e-9 or round(steps) < 1:
            raise ValueError(
                f'physics rate {physics_rate_hz} Hz must be a multiple of the policy rate {policy_rate_hz} Hz'
            )
        if arm_substeps < 1:
            raise ValueError('arm_substeps must be at least 1')
        self.num_envs = int(num_envs)
        self.device = torch.device(device)
        self.dtype = dtype
        self.policy_dt_s = 1.0 / policy_rate_hz
        self.physics_dt_s = 1.0 / physics_rate_hz
        self.physics_steps = int(round(steps))
        self.arm_substeps = int(arm_substeps)
        self.timeout_s = float(timeout_s)
        # Intra-op threads while stepping on the CPU (see torch_threads); None keeps the caller's.
        self.cpu_threads = cpu_threads if self.device.type == 'cpu' else None
        # Physics steps between updates of the inertia and bias torques: by default once per policy
        # step (measured: agreement with the cell unchanged, 1.2-1.8 % either way; half the cost).
        self.dynamics_every = self.physics_steps if dynamics_every is None else int(dynamics_every)
        # Whether params.velocity_drive is stepped at all: the motor's torques and gravity cost the world
        # about an eighth of its step (benchmarked with 1024 environments), so worlds without it skip them.
        self.velocity_drive = bool(velocity_drive)
        if self.dynamics_every < 1:
            raise ValueError('dynamics_every must be at least 1')
        self.model = batched_kinematics.build_arm_model(self.device, dtype)
        self.params = PhysicsParams.nominal(num_envs, self.device, dtype)
        n, kw = self.num_envs, dict(device=self.device, dtype=dtype)
        home = torch.tensor(world_spec.HOME_JOINT_POSITIONS_RAD, **kw)[:, None]
        self.q_rad = home.repeat(1, n)
        self.qd_rad_s = torch.zeros(6, n, **kw)
        self.q_ref_rad = self.q_rad.clone()
        self.q_cmd_rad = self.q_rad.clone()  # the target the servo is tracking now
        self.q_issued_rad = self.q_rad.clone()  # the latest command given to `step` (delayed to the servo)
        self.ball_pos_m = torch.zeros(3, n, **kw)
        self.ball_vel_m_s = torch.zeros(3, n, **kw)
        self.time_s = torch.zeros(n, **kw)
        self.hit = torch.zeros(n, dtype=torch.bool, device=self.device)
        self.own_bounces = torch.zeros(n, dtype=torch.long, device=self.device)
        self.open = torch.zeros(n, dtype=torch.bool, device=self.device)
        self.success = torch.zeros(n, dtype=torch.bool, device=self.device)
        self.reason = torch.full((n,), referee.NO_VERDICT, dtype=torch.long, device=self.device)
        self.landing_xy_m = torch.zeros(2, n, **kw)
        self._eye6 = torch.eye(6, **kw)[..., None]  # [6, 6, 1]
        self.table_contact_pos_m = torch.zeros(3, n, **kw)
        self._kin = batched_kinematics.forward_kinematics(self.model, self.q_rad)
        self._constants()
        self._forward_kinematics = batched_kinematics.forward_kinematics
        if compile:
            # torch.compile (inductor) fuses each stage's hundreds of small operations into a few loops:
            # measured 3-4x faster per stage on this CPU, after 1-2 minutes of compilation at start.
            self._forward_kinematics = torch.compile(batched_kinematics.forward_kinematics, dynamic=False)
            self._arm_dynamics = torch.compile(self._arm_dynamics, dynamic=False)
            self._arm_step = torch.compile(self._arm_step, dynamic=False)
            self._ball_step = torch.compile(self._ball_step, dynamic=False)

    def _constants(self) -> None:
        kw = dict(device=self.device, dtype=self.dtype)
        self._up = torch.tensor([0.0, 0.0, 1.0], **kw)[:, None]
        r = world_spec.BALL_RADIUS_M
        self._net_lo = torch.tensor(world_spec.NET_BOX_LOW_M, **kw)[:, None]
        self._net_hi = torch.tensor(world_spec.NET_BOX_HIGH_M, **kw)[:, None]
        self._link_reach_sq_m2 = (self.model.capsule_radius_m + r) ** 2  # [L, 1]
        # Both end spheres of every capsule, in the order capsule_segments' a, b are concatenated.
        radius = torch.cat((self.model.capsule_radius_m, self.model.capsule_radius_m))  # [2L, 1]
        self._capsule_end_radius_sq_m2 = radius * radius
        self._blade_radius_m = robot_model.PADDLE.blade_radius_m
        self._blade_half_thickness_m = robot_model.PADDLE.blade_thickness_m / 2.0

    # --- public views (after the last step; environment axis last, as everywhere here) --------------
    @property
    def paddle_pos_m(self) -> torch.Tensor:
        """[3, N] the blade centre in the world."""
        return self._kin.paddle_pos_m

    @property
    def paddle_rot(self) -> torch.Tensor:
        """[3, 3, N] columns: the paddle_centre frame's axes in the world (z: the blade's face normal)."""
        return self._kin.paddle_rot

    @property
    def kinematics(self) -> Kinematics:
        return self._kin

    # --- resets --------------------------------------------------------------------------------------
    def reset_envs(
        self,
        env_ids: torch.Tensor,
        q_rad: torch.Tensor,
        ball_pos_m: torch.Tensor,
        ball_vel_m_s: torch.Tensor,
        params: PhysicsParams | None = None,
        qd_rad_s: torch.Tensor | None = None,
    ) -> None:
        """Put the arm of environments env_ids at rest (or qd) at q [6, k], launch a ball [3, k], open a rally."""
        if env_ids.numel() == 0:
            return
        q = torch.maximum(torch.minimum(q_rad, self.model.upper_rad), self.model.lower_rad)
        self.q_rad[:, env_ids] = q
        self.qd_rad_s[:, env_ids] = 0.0 if qd_rad_s is None else qd_rad_s
        self.q_ref_rad[:, env_ids] = q
        self.q_cmd_rad[:, env_ids] = q
        self.q_issued_rad[:, env_ids] = q
        self.ball_pos_m[:, env_ids] = ball_pos_m
        self.ball_vel_m_s[:, env_ids] = ball_vel_m_s
        self.time_s[env_ids] = 0.0
        self.hit[env_ids] = False
        self.own_bounces[env_ids] = 0
        self.open[env_ids] = True
        self.success[env_ids] = False
        self.reason[env_ids] = referee.NO_VERDICT
        self.landing_xy_m[:, env_ids] = 0.0
        if params is not None:
            self.params.assign(env_ids, params)
        self._kin = batched_kinematics.forward_kinematics(self.model, self.q_rad)

    # --- stepping ------------------------------------------------------------------------------------
    def step(self, q_cmd_rad: torch.Tensor, delay_steps: torch.Tensor | None = None) -> StepEvents:
        """Apply the joint position command q_cmd [6, N] for one policy period; returns its events.

        delay_steps [N] (long, 0..physics_steps): the command reaches the servo only after that many
        physics steps (the previous command given to `step` holds until then): the action latency of a
        real cell. With physics_steps it takes effect at the start of the next period.
        """
        with torch_threads(self.cpu_threads):
            return self._step(q_cmd_rad, delay_steps)

    def _step(self, q_cmd_rad: torch.Tensor, delay_steps: torch.Tensor | None) -> StepEvents:
        # The delayed command is the previous *issued* one, not the servo's current target: with a delay of
        # a whole policy period the target would otherwise hold its old value forever.
        previous = self.q_issued_rad
        command = torch.maximum(torch.minimum(q_cmd_rad, self.model.upper_rad), self.model.lower_rad)
        self.q_issued_rad = command
        paddle_hit = torch.zeros(self.num_envs, dtype=torch.bool, device=self.device)
        own_bounce = torch.zeros_like(paddle_hit)
        was_open = self.open.clone()
        for k in range(self.physics_steps):
            self.q_cmd_rad = command if delay_steps is None else torch.where(delay_steps > k, previous, command)
            kin_before = self._kin
            if k % self.dynamics_every == 0:
                dynamics = self._arm_dynamics(kin_before)
            self._arm_step(dynamics)
            self._kin = self._forward_kinematics(self.model, self.q_rad)
            hit, bounce = self._ball_step(kin_before, self._kin)
            paddle_hit = paddle_hit | hit
            own_bounce = own_bounce | bounce
        decided = was_open & ~self.open
        return StepEvents(
            paddle_hit=paddle_hit,
            own_bounce=own_bounce,
            decided=decided,
            success=self.success & decided,
            reason=torch.where(decided, self.reason, referee.NO_VERDICT),
        )

    # --- the arm -------------------------------------------------------------------------------------
    def _arm_dynamics(self, kin: Kinematics) -> ArmDynamics:
        """The arm's joint-space dynamics at the current state."""
        sp = batched_kinematics.spatial(self.model, kin)
        inertia = batched_kinematics.mass_matrix(sp) + self._eye6 * self.params.armature_kg_m2[None]
        inverse = torch.linalg.inv_ex(inertia.permute(2, 0, 1))[0].permute(1, 2, 0)
        coriolis = batched_kinematics.bias_torques(sp, self.qd_rad_s)
        gravity = (
            batched_kinematics.bias_torques(sp, torch.zeros_like(self.qd_rad_s), self.params.gravity_m_s2)
            if self.velocity_drive
            else None
        )
        return ArmDynamics(inertia, inverse, coriolis, gravity)

    def _arm_step(self, dynamics: ArmDynamics) -> None:
        """One physics step of the servo law (world_spec) in arm_substeps sub-steps, with the dynamics of
        `_arm_dynamics` held.

        Damping is explicit: MuJoCo's implicitfast drops a saturated actuator's damping derivative, so
        under saturation (a swing's start) the cell's law is the explicit one; at 480 Hz it is stable for
        the stiffest joint (Kd dt / I = 0.7 for wrist 3) and agrees with the cell within ~2 %.
        In a world built with velocity_drive, where `params.velocity_drive` w > 0 the drive torque is
        (1 - w) PD + w motor. The motor's is the torque that reaches v_ref + (Kp / Kd)(q_ref - q) in one
        sub-step (exact, so stable at any stiffness), gravity's share included in its effort limit, as in
        Bullet's motors and a real arm's drives.
        """
        m = self.model
        dt = self.physics_dt_s / self.arm_substeps
        kp, kd = self.params.kp_nm_per_rad, self.params.kd_nms_per_rad
        motor_share, position_gain = self.params.velocity_drive, kp / kd
        v_max, effort = m.velocity_limit_rad_s, m.effort_limit_nm
        step_max = v_max * dt
        q, qd, q_ref = self.q_rad, self.qd_rad_s, self.q_ref_rad
        inertia, inverse, coriolis, gravity = dynamics
        for _ in range(self.arm_substeps):
            delta = torch.maximum(torch.minimum(self.q_cmd_rad - q_ref, step_max), -step_max)
            q_ref = q_ref + delta
            v_ref = delta / dt
            # Net of gravity: the PD's clipped torque (its gravity compensated outside the clip), the motor's
            # clipped torque less gravity.
            pd = kp * (q_ref - q) + kd * (v_ref - qd)
            torque = torch.maximum(torch.minimum(pd, effort), -effort)
            if self.velocity_drive:
                wanted_acceleration = (v_ref + position_gain * (q_ref - q) - qd) / dt
                motor = coriolis + gravity + inertia[:, 0] * wanted_acceleration[0]
                for j in range(1, 6):
                    motor = motor + inertia[:, j] * wanted_acceleration[j]
                motor = torch.maximum(torch.minimum(motor, effort), -effort) - gravity
                torque = torque + motor_share * (motor - torque)
            torque = torque - coriolis
            qdd = inverse[:, 0] * torque[0]
            for j in range(1, 6):
                qdd = qdd + inverse[:, j] * torque[j]
            qd = qd + qdd * dt
            q = q + qd * dt
            qd = torch.maximum(torch.minimum(qd, v_max), -v_max)
        self.q_rad = torch.maximum(torch.minimum(q, m.upper_rad), m.lower_rad)
        self.qd_rad_s, self.q_ref_rad = qd, q_ref

    # --- the ball ------------------------------------------------------------------------------------
    def _free_flight(self, v: torch.Tensor, dt) -> tuple[torch.Tensor, torch.Tensor]:
        """Midpoint rule for gravity + drag over dt ([N] or float): (displacement, new velocity)."""
        g = self.params.gravity_m_s2
        k = self.params.drag_k_per_m

        def accel(u):
            a = -k * torch.sqrt(batched_kinematics.dot(u, u)) * u
            return torch.stack((a[0], a[1], a[2] - g))

        v_half = v + 0.5 * dt * accel(v)
        return v_half * dt, v + dt * accel(v_half)

    def _ball_step(self, kin0: Kinematics, kin1: Kinematics) -> tuple[torch.Tensor, torch.Tensor]:
        """One physics step of the ball and the referee; returns (paddle hit, own-side bounce) flags."""
        p0, v0 = self.ball_pos_m, self.ball_vel_m_s
        displacement, v1 = self._free_flight(v0, self.physics_dt_s)
        p1 = p0 + displacement
        contact, capsule_a, capsule_b = self._earliest_contact(kin0, kin1, p0, p1, v1)
        p_new, v_new = self._bounce(contact, p0, v0, p1, v1)
        return self._judge(kin1, capsule_a, capsule_b, contact, p_new, v_new)

    def _table_contact(self, p0: torch.Tensor, p1: torch.Tensor) -> torch.Tensor:
        """Fraction of the step [N] at which the ball's bottom crosses the table top's plane over the table."""
        contact_z = world_spec.TABLE_CONTACT_HEIGHT_M
        f_table = (p0[2] - contact_z) / (p0[2] - p1[2])
        at = p0 + f_table * (p1 - p0)
        table_ok = (p0[2] >= contact_z) & (p1[2] < contact_z) & world_spec.on_table(at[0], at[1])
        return torch.where(table_ok, f_table, _NO_CONTACT)

    def _net_contact(
        self, p0: torch.Tensor, p1: torch.Tensor, v1: torch.Tensor
    ) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """The net: its two faces swept exactly; its top and ends by the end position against its box.
        Returns (fraction [N], normal [3, N], ball centre at the contact [3, N])."""
        r = world_spec.BALL_RADIUS_M
        face_x = world_spec.NET_FACE_CONTACT_X_M
        side_net = torch.where(p0[0] >= 0.0, 1.0, -1.0).to(self.dtype)
        s0, s1 = side_net * p0[0], side_net * p1[0]
        f_net = (s0 - face_x) / (s0 - s1)
        at = p0 + f_net * (p1 - p0)
        net_face = (
            (s0 >= face_x)
            & (s1 < face_x)
            & (at[1].abs() <= world_spec.NET_LENGTH_M / 2)
            & (at[2] > world_spec.TABLE_HEIGHT_M)
            & (at[2] <= world_spec.NET_TOP_HEIGHT_M)
        )
        closest_net = torch.maximum(torch.minimum(p1, self._net_hi), self._net_lo)
        offset_net = p1 - closest_net
        dist_net = torch.sqrt(batched_kinematics.dot(offset_net, offset_net))
        normal_net_box = offset_net / dist_net.clamp_min(1e-9)
        net_box = ~net_face & (dist_net < r) & (dist_net > 0.0) & (batched_kinematics.dot(v1, normal_net_box) < 0.0)
        f_net = torch.where(net_face, f_net, torch.where(net_box, torch.ones_like(f_net), _NO_CONTACT))
        normal_net = torch.where(net_face, torch.stack((side_net, 0.0 * side_net, 0.0 * side_net)), normal_net_box)
        centre_net = torch.where(net_face, p0 + f_net.clamp(max=1.0) * (p1 - p0), closest_net + normal_net_box * r)
        centre_net[0] = torch.where(net_face, side_net * face_x, centre_net[0])
        return f_net, normal_net, centre_net

    def _blade_contact(
        self, kin0: Kinematics, kin1: Kinematics, p0: torch.Tensor, p1: torch.Tensor, v1: torch.Tensor
    ) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor, torch.Tensor]:
        """The blade: its faces swept in its moving frame (positions relative to the blade before and after
        the step), its rim by the end position. Returns (fraction [N], normal, ball centre at the contact,
        the blade's velocity there [3, N])."""
        r = world_spec.BALL_RADIUS_M
        c0, rot0 = kin0.paddle_pos_m, kin0.paddle_rot
        c1, rot1 = kin1.paddle_pos_m, kin1.paddle_rot
        local0 = batched_kinematics.mat_t_vec(rot0, p0 - c0)
        local1 = batched_kinematics.mat_t_vec(rot1, p1 - c1)
        h, radius = self._blade_half_thickness_m, self._blade_radius_m
        face_z = h + r
        side_pad = torch.where(local0[2] >= 0.0, 1.0, -1.0).to(self.dtype)
        s0, s1 = side_pad * local0[2], side_pad * local1[2]
        f_face = (s0 - face_z) / (s0 - s1)
        local_at = local0 + f_face * (local1 - local0)
        face_hit = (s0 >= face_z) & (s1 < face_z) & (local_at[0] ** 2 + local_at[1] ** 2 <= radius**2)
        local_face = torch.stack((local_at[0], local_at[1], side_pad * face_z))
        # Rim (and a ball found inside the blade's slab): the end position against the solid disc.
        rho = torch.sqrt(local1[0] ** 2 + local1[1] ** 2)
        scale = (radius / rho.clamp_min(1e-9)).clamp(max=1.0)
        closest_rim = torch.stack((local1[0] * scale, local1[1] * scale, local1[2].clamp(-h, h)))
        offset_rim = local1 - closest_rim
        dist_rim = torch.sqrt(batched_kinematics.dot(offset_rim, offset_rim))
        face_normal_local = torch.stack((0.0 * side_pad, 0.0 * side_pad, side_pad))
        rim_normal_local = torch.where(dist_rim > 0.0, offset_rim / dist_rim.clamp_min(1e-9), face_normal_local)
        normal_pad = batched_kinematics.mat_vec(rot1, torch.where(face_hit, face_normal_local, rim_normal_local))
        surface_local = torch.where(face_hit, local_face - torch.stack((0.0 * s0, 0.0 * s0, side_pad * r)), closest_rim)
        surface_pad = c1 + batched_kinematics.mat_vec(rot1, surface_local)
        u_pad = self._point_velocity(kin1, surface_pad)
        rim_hit = ~face_hit & (dist_rim < r) & (batched_kinematics.dot(v1 - u_pad, normal_pad) < 0.0)
        f_pad = torch.where(face_hit, f_face, torch.where(rim_hit, torch.ones_like(f_face), _NO_CONTACT))
        centre_pad = surface_pad + normal_pad * r
        return f_pad, normal_pad, centre_pad, u_pad

    def _earliest_contact(
        self, kin0: Kinematics, kin1: Kinematics, p0: torch.Tensor, p1: torch.Tensor, v1: torch.Tensor
    ) -> tuple[_Contact, torch.Tensor, torch.Tensor]:
        """The earliest of the table, net and blade contacts in the step; robot links only when nothing else
        was touched. Returns it with the robot's capsules [3, L, N] (end points a, b) at the step's end."""
        f_table = self._table_contact(p0, p1)
        f_net, normal_net, centre_net = self._net_contact(p0, p1, v1)
        f_pad, normal_pad, centre_pad, u_pad = self._blade_contact(kin0, kin1, p0, p1, v1)
        f = torch.minimum(torch.minimum(f_table, f_net), f_pad)
        kind = torch.where(f > 1.0, _NONE, torch.where(f == f_table, _TABLE, torch.where(f == f_net, _NET, _PADDLE)))
        capsule_a, capsule_b = batched_kinematics.capsule_segments(self.model, kin1)
        robot = (kind == _NONE) & self._touches_links(capsule_a, capsule_b, p1)
        f = torch.where(kind == _NONE, torch.ones_like(f), f)
        is_table, is_net, is_pad = kind == _TABLE, kind == _NET, kind == _PADDLE
        normal = torch.where(is_table, self._up, torch.where(is_net, normal_net, normal_pad))
        centre = torch.where(is_table, p0 + f * (p1 - p0), torch.where(is_net, centre_net, centre_pad))
        centre[2] = torch.where(is_table, torch.full_like(f, world_spec.TABLE_CONTACT_HEIGHT_M), centre[2])
        surface_velocity = torch.where(is_pad, u_pad, torch.zeros_like(u_pad))
        contact = _Contact(
            kind=kind,
            fraction=f,
            robot_link=robot,
            centre_m=centre,
            normal=normal,
            surface_velocity_m_s=surface_velocity,
        )
        return contact, capsule_a, capsule_b

    def _bounce(
        self, contact: _Contact, p0: torch.Tensor, v0: torch.Tensor, p1: torch.Tensor, v1: torch.Tensor
    ) -> tuple[torch.Tensor, torch.Tensor]:
        """The ball's position and velocity [3, N] at the step's end: off the surface it touched
        (world_spec.contact_response) and flown for the rest of the step, or as flown where it touched none."""
        f, kind = contact.fraction, contact.kind
        is_table, is_net = kind == _TABLE, kind == _NET
        restitution = torch.where(
            is_table,
            self.params.table_restitution,
            torch.where(is_net, torch.full_like(f, world_spec.NET_RESTITUTION), self.params.paddle_restitution),
        )
        tangential = torch.where(
            is_table,
            self.params.table_tangential_factor,
            torch.where(
                is_net, torch.full_like(f, world_spec.NET_TANGENTIAL_FACTOR), self.params.paddle_tangential_factor
            ),
        )
        surface_velocity = contact.surface_velocity_m_s
        v_at = v0 + f * (v1 - v0)
        relative = (v_at - surface_velocity).T
        v_out = (
            surface_velocity
            + world_spec.contact_response(relative, contact.normal.T, restitution[:, None], tangential[:, None]).T
        )
        rest = (1.0 - f) * self.physics_dt_s
        displacement, v_after = self._free_flight(v_out, rest)
        touched = kind != _NONE
        return torch.where(touched, contact.centre_m + displacement, p1), torch.where(touched, v_after, v1)

    def _judge(
        self,
        kin1: Kinematics,
        capsule_a: torch.Tensor,
        capsule_b: torch.Tensor,
        contact: _Contact,
        p_new: torch.Tensor,
        v_new: torch.Tensor,
    ) -> tuple[torch.Tensor, torch.Tensor]:
        """The referee's rules (stylepong_sim.referee, the same functions and order as the cell's referee) for
        this step's contact and the ball's state after it; updates the rally state and returns the flags
        (paddle's first hit, own-side bounce) [N]."""
        open_ = self.open
        verdict = torch.full((self.num_envs,), referee.NO_VERDICT, dtype=torch.long, device=self.device)

        def decide(mask: torch.Tensor, reason: str) -> None:
            nonlocal verdict
            verdict = torch.where(mask & (verdict == referee.NO_VERDICT), referee.REASON_INDEX[reason], verdict)

        def decide_all(event: torch.Tensor, verdicts: referee.Verdicts) -> None:
            for reason, holds in verdicts:
                decide(event & holds, reason)

        decide(open_ & self._robot_touches_table(kin1, capsule_a, capsule_b), referee.REASON_TABLE_CONTACT_BY_ROBOT)
        centre, kind = contact.centre_m, contact.kind
        own_side = referee.is_own_side(centre)
        table_event = open_ & (kind == _TABLE)
        own_bounce = table_event & referee.own_side_bounce(self.hit, own_side)
        self.own_bounces = self.own_bounces + own_bounce.long()
        decide_all(table_event, referee.table_contact_verdicts(self.hit, own_side, self.own_bounces))
        decide_all(open_ & (kind == _NET), referee.net_contact_verdicts(self.hit))
        pad_event = open_ & (kind == _PADDLE)
        decide_all(pad_event, referee.paddle_contact_verdicts(self.hit))
        first_hit = pad_event & ~self.hit
        decide(open_ & contact.robot_link, referee.REASON_ROBOT_CONTACT)
        self.landing_xy_m = torch.where(table_event & self.hit, centre[:2], self.landing_xy_m)
        self.table_contact_pos_m = torch.where(kind == _TABLE, centre, self.table_contact_pos_m)
        hit_after = self.hit | first_hit
        # After the step: dead, out and timeout (time since the launch).
        time_s = self.time_s + self.physics_dt_s
        state_verdicts = referee.ball_state_verdicts(hit_after, p_new, v_new[2], time_s, self.timeout_s)
        # Out balls: where the referee calls them out.
        newly_out = open_ & dict(state_verdicts)[referee.REASON_OUT] & (verdict == referee.NO_VERDICT)
        self.landing_xy_m = torch.where(newly_out, p_new[:2], self.landing_xy_m)
        decide_all(open_, state_verdicts)

        decided = verdict != referee.NO_VERDICT
        self.reason = torch.where(decided, verdict, self.reason)
        self.success = self.success | (decided & (verdict == referee.REASON_INDEX[referee.REASON_RETURNED]))
        self.open = open_ & ~decided
        self.hit = hit_after
        self.time_s = time_s
        self.ball_pos_m, self.ball_vel_m_s = p_new, v_new
        return first_hit, own_bounce

    def _point_velocity(self, kin: Kinematics, point_m: torch.Tensor) -> torch.Tensor:
        """World velocity [3, N] of a point [3, N] fixed to the last link, at joint velocities qd."""
        qd = self.qd_rad_s
        omega = (kin.axis * qd).sum(1)
        v_flange = (batched_kinematics.cross(kin.axis, kin.origin_m[:, -1:] - kin.origin_m) * qd).sum(1)
        return v_flange + batched_kinematics.cross(omega, point_m - kin.origin_m[:, -1])

    def _touches_links(self, a: torch.Tensor, b: torch.Tensor, p: torch.Tensor) -> torch.Tensor:
        """The ball centre p [3, N] within a ball radius of any capsule a-b [3, L, N] (the handle included)."""
        ab = b - a
        ap = p[:, None] - a
        t = (batched_kinematics.dot(ap, ab) / batched_kinematics.dot(ab, ab).clamp_min(1e-12)).clamp(0.0, 1.0)
        d = ap - t * ab
        return (batched_kinematics.dot(d, d) < self._link_reach_sq_m2).any(0)

    def commands_below_table_top(self, q_cmd_rad: torch.Tensor) -> torch.Tensor:
        """[N] bool: the arm at the commanded joint positions [6, N] would have geometry over the table and
        below its top, inside the slab or under it. A stiff drive takes the arm where it is commanded, so
        such a command drives it into the table; the PD's lag only hides it (docs/DESIGN.md, Known limits)."""
        kin = batched_kinematics.forward_kinematics(self.model, q_cmd_rad)
        a, b = batched_kinematics.capsule_segments(self.model, kin)
        return self._robot_touches_table(kin, a, b, bottom_m=-math.inf)

    def _robot_touches_table(
        self,
        kin: Kinematics,
        a: torch.Tensor,
        b: torch.Tensor,
        bottom_m: float = world_spec.TABLE_HEIGHT_M - world_spec.TABLE_THICKNESS_M,
    ) -> torch.Tensor:
        """Any robot geometry inside the table top (between bottom_m and the top surface): the capsules'
        end spheres (a segment's lowest point is one of its ends) and the blade's lowest point."""
        points = torch.cat((a, b), dim=1)  # [3, 2L, N]
        gap_x = (points[0].abs() - world_spec.HALF_LENGTH_M).clamp_min(0.0)
        gap_y = (points[1].abs() - world_spec.HALF_WIDTH_M).clamp_min(0.0)
        gap_z = (points[2] - world_spec.TABLE_HEIGHT_M).clamp_min(0.0) + (bottom_m - points[2]).clamp_min(0.0)
        touching = (gap_x * gap_x + gap_y * gap_y + gap_z * gap_z < self._capsule_end_radius_sq_m2).any(0)
        # The blade: a disc of radius R and half thickness h; its lowest point.
        normal = kin.paddle_rot[:, 2]
        nz = normal[2].clamp(-1.0, 1.0)
        in_plane = torch.sqrt((1.0 - nz * nz).clamp_min(1e-12))
        scale = self._blade_radius_m / in_plane
        lowest_x = kin.paddle_pos_m[0] + scale * nz * normal[0]
        lowest_y = kin.paddle_pos_m[1] + scale * nz * normal[1]
        lowest_z = kin.paddle_pos_m[2] - self._blade_radius_m * in_plane - self._blade_half_thickness_m * nz.abs()
        blade = world_spec.on_table(lowest_x, lowest_y) & (lowest_z < world_spec.TABLE_HEIGHT_M) & (lowest_z > bottom_m)
        return touching | blade
