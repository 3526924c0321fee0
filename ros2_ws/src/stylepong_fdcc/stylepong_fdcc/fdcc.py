"""Forward Dynamics Compliance Control (FDCC, Scherzinger et al. 2017) with the safety a real arm needs.

No ROS in here: `drag_teach_node` only wires topics, services and a timer to `DragTeachController`.

Method
------
The arm is driven by a simulated copy of itself. Each control cycle the Cartesian task force at the
control frame `tool0`

    F_t = K_P (x_d - x) - K_D xdot                      (6-vector, base_link axes, at tool0's origin)

and the conditioned external wrench F_ext (what the hand applies on the tool) act through J^T on a
gravity-free dynamics model, and the joint accelerations come from forward dynamics:

    M(q) qddot + C(q, qdot) qdot = J^T (F_ext + F_t) - D_joint qdot

The paper writes ForwardDynamics(..., F_ext - F_t); with F_t defined as above that sign would turn K_D
into a negative damper, so the signs here are the physical ones: the hand's push and the task force
both act on the arm. The damping terms are integrated implicitly (linearly implicit Euler over the real
control period dt):

    (M + dt J^T K_D J + dt D_joint + dt^2 J^T K_P J) qdot+ = M qdot + dt (J^T (F_ext + K_P (x_d - x)) - C qdot)
    q+ = q + dt qdot+

which is stable for any gain and period and makes the admittance independent of the control rate: for
a push of impulse I the tool comes to rest I / K_D further on whatever the rate (a 10 N, 1 s push at
250 Hz and at 1000 Hz ends 0.33 m away with both models, the two within 0.11 % of each other;
test_fdcc_solver.py requires 5 %). Gains are in physical
units: K_D in N s/m (x, y, z) and N m s/rad (rx, ry, rz); K_P in N/m and N m/rad; K_P = 0 for dragging.

Dynamics model (`dynamics_model`)
---------------------------------
"virtual" (default): like FZI cartesian_controllers, every moving link gets a small mass (0.1 kg at its
joint origin, inertia 1e-6 kg m^2) and the last link a larger one (1 kg, 0.01 kg m^2); "urdf": the
URDF's own inertias (UR5 + paddle, 21 kg) with gravity off. A 10 N push along +x of base_link for 1 s
from the home pose, default damping (30 N s/m, 3 N m s/rad), 500 Hz:

    solver alone, a perfect servo (`python3 -m stylepong_fdcc.fdcc`):
    model    rise to 90 % speed   moved during the push   coasts after release   at rest after release
    virtual        0.12 s               0.306 m                 0.023 m                 0.19 s
    urdf           0.64 s               0.225 m                 0.102 m                 1.19 s
    through the MuJoCo cell (stylepong_sim.cell: servo, F/T sensor; 4 ms transport each way):
    virtual        0.10 s               0.277 m                 0.020 m                 0.14 s
    urdf           0.55 s               0.198 m                 0.094 m                 0.99 s

Both end 0.29-0.33 m along +x (impulse / damping, direction cosine 0.9999). The URDF model feels like
its mass: its effective mass at the tool is 4.0-10.7 kg depending on direction (1.1-1.3 kg for the
virtual model), so the arm lags the hand for half a second, and after the hand lets go it carries on
for another 10 cm and a second. The virtual model follows the hand within a tenth of a second and
stops where the hand stops, which is what a person dragging it expects, so it is the default.

Safety layer (docs/DESIGN.md, "FDCC safety layer")
--------------------------------------------------
What users of FZI cartesian_controllers have asked for in its issue tracker: no drift from the tool's
weight after the tool is reoriented, a sensor bias taken at start-up, a filtered wrench against
oscillation at high rates and in stiff contact, joint velocity and acceleration limits (not only
position clamping), and one clear sign and frame for the sensor wrench.
- NaN/inf rejection: a wrench or joint state with a non-finite entry is rejected; implausible wrenches
  (beyond `reject_force_n` / `reject_torque_nm`, well beyond any sensor's range) are rejected too.
- Tool gravity compensation: the sensor reading includes the paddle's weight; the paddle's mass and
  centre of mass come from the robot model (`stylepong_description`) and its weight is removed at the
  current tool orientation (no drift after reorienting the tool).
- Taring: the sensor bias is the mean gravity-compensated reading over the last `tare_window_s`;
  taken at start and on request (`/drag_teach/tare`).
- Low-pass (first order, cutoff in Hz, discretised with the real sample interval), a deadband (the
  magnitude is reduced by the deadband, so the response stays continuous), a magnitude clamp.
- Joint limits: positions stay `position_margin_rad` inside the URDF's (the arm brakes at the
  acceleration limit before reaching them), velocities within `velocity_limit_scale` x the URDF's and
  accelerations within `acceleration_limit_rad_s2`; velocity and acceleration are limited by scaling
  the whole joint vector, so the tool keeps its direction. A command never moves a joint more than
  its velocity limit times the nominal period from the previous one, even after a late tick (the
  command then catches up with the simulated arm over the next cycles). A stall longer than
  `max_late_periods` control periods is integrated as that many: the arm carries on, it does not jump.
- Watchdog: no valid wrench or joint state for `watchdog_timeout_s` (50 ms): the simulated arm
  decelerates at the acceleration limit along its path and holds; it resumes when both are fresh,
  fading the wrench back in over `resume_ramp_s` (a hand that kept pushing must not make it lurch).
- The simulated q, qdot are synchronised from the measured joints only when control is (re-)enabled,
  never each cycle: re-syncing would feed the servo's tracking error back in as motion (drift,
  spring-back). While enabled the command is the simulated arm, which is at rest unless pushed.
"""
from __future__ import annotations

import collections
import math
import time
from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from stylepong_description import robot_model as rm

DYNAMICS_MODELS = ('virtual', 'urdf')


# ---------------------------------------------------------------------------------------------------
# Configuration
# ---------------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class FdccConfig:
    """All settings of the solver and its safety layer; the node fills it from its parameters."""
    # Gains: (x, y, z) in N s/m resp. N/m, then (rx, ry, rz) in N m s/rad resp. N m/rad, base_link axes.
    damping: tuple[float, ...] = (30.0, 30.0, 30.0, 3.0, 3.0, 3.0)
    stiffness: tuple[float, ...] = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
    joint_damping_nms_per_rad: float = 0.05   # keeps motions J cannot see (singularities) damped
    dynamics_model: str = 'virtual'
    virtual_link_mass_kg: float = 0.1
    virtual_link_inertia_kg_m2: float = 1e-6
    virtual_end_mass_kg: float = 1.0
    virtual_end_inertia_kg_m2: float = 0.01
    nominal_period_s: float = 0.002           # 1 / control rate
    # A gap between cycles longer than this many nominal periods (a stalled process, not a skipped tick)
    # is integrated as this many: after a stall the arm carries on instead of jumping to catch up.
    max_late_periods: float = 2.0
    # Wrench conditioning.
    gravity_compensation: bool = True
    lowpass_cutoff_hz: float = 20.0
    force_deadband_n: float = 1.0
    torque_deadband_nm: float = 0.1
    max_force_n: float = 40.0
    max_torque_nm: float = 4.0
    reject_force_n: float = 500.0
    reject_torque_nm: float = 50.0
    tare_window_s: float = 0.2
    # Joint limits.
    position_margin_rad: float = 0.05
    velocity_limit_scale: float = 1.0         # x the URDF's velocity limits
    acceleration_limit_rad_s2: tuple[float, ...] = (8.0, 8.0, 8.0, 12.0, 12.0, 12.0)
    # Watchdog.
    watchdog_timeout_s: float = 0.05
    resume_ramp_s: float = 0.2                # after a hold the wrench fades back in over this time

    def validate(self) -> None:
        """Raise ValueError naming the first bad setting."""
        def vec(name, n=6, positive=False):
            v = np.asarray(getattr(self, name), dtype=float)
            if v.shape != (n,) or not np.all(np.isfinite(v)) or np.any(v < 0) or (positive and np.any(v == 0)):
                raise ValueError(f'{name} must be {n} finite {"positive" if positive else "non-negative"} numbers, '
                                 f'got {getattr(self, name)!r}')
        vec('damping', positive=True)
        vec('stiffness')
        vec('acceleration_limit_rad_s2', positive=True)
        if self.dynamics_model not in DYNAMICS_MODELS:
            raise ValueError(f'dynamics_model must be one of {DYNAMICS_MODELS}, got {self.dynamics_model!r}')
        positive = ('virtual_link_mass_kg', 'virtual_link_inertia_kg_m2', 'virtual_end_mass_kg',
                    'virtual_end_inertia_kg_m2', 'nominal_period_s', 'lowpass_cutoff_hz',
                    'max_force_n', 'max_torque_nm', 'reject_force_n', 'reject_torque_nm', 'tare_window_s',
                    'watchdog_timeout_s', 'resume_ramp_s')
        for name in positive:
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise ValueError(f'{name} must be a positive number, got {value!r}')
        for name in ('joint_damping_nms_per_rad', 'force_deadband_n', 'torque_deadband_nm', 'position_margin_rad'):
            value = getattr(self, name)
            if not (math.isfinite(value) and value >= 0):
                raise ValueError(f'{name} must be a non-negative number, got {value!r}')
        if not 0 < self.velocity_limit_scale <= 1.0:
            raise ValueError(f'velocity_limit_scale must be in (0, 1], got {self.velocity_limit_scale!r}')
        if not (math.isfinite(self.max_late_periods) and self.max_late_periods >= 1.0):
            raise ValueError(f'max_late_periods must be at least 1, got {self.max_late_periods!r}')
        if self.max_force_n >= self.reject_force_n or self.max_torque_nm >= self.reject_torque_nm:
            raise ValueError('the clamp (max_force_n, max_torque_nm) must lie below the rejection thresholds')


# ---------------------------------------------------------------------------------------------------
# Models
# ---------------------------------------------------------------------------------------------------
def dynamics_model(config: FdccConfig) -> pin.Model:
    """The gravity-free model the solver integrates: the URDF's inertias, or FZI-style light links."""
    model = rm.pinocchio_model()
    model.gravity = pin.Motion.Zero()
    if config.dynamics_model == 'virtual':
        last = model.njoints - 1
        for joint in range(1, model.njoints):
            mass, inertia = ((config.virtual_end_mass_kg, config.virtual_end_inertia_kg_m2) if joint == last
                             else (config.virtual_link_mass_kg, config.virtual_link_inertia_kg_m2))
            model.inertias[joint] = pin.Inertia(mass, np.zeros(3), inertia * np.eye(3))
    return model


@dataclass(frozen=True)
class ToolLoad:
    """What hangs on the sensor: mass and centre of mass (tool0 frame) of the paddle."""
    mass_kg: float
    com_m: np.ndarray


def tool_load_from_model(model: pin.Model) -> ToolLoad:
    """The paddle's mass and centre of mass in tool0, as the robot model describes them.

    Pinocchio folds fixed links into their parent joint's body but keeps each fixed link's inertia on
    the frame of the fixed joint that attaches it; that is where the paddle's numbers are read.
    """
    paddle = model.frames[model.getFrameId(rm.PADDLE_BODY)]
    attach = model.frames[paddle.parentFrame]
    tool = model.frames[model.getFrameId(rm.TOOL_FRAME)]
    # Both frames hang on the same joint: tool0 <- joint -> attachment frame.
    tool_m_attach = tool.placement.actInv(attach.placement)
    return ToolLoad(mass_kg=float(attach.inertia.mass), com_m=np.array(tool_m_attach.act(attach.inertia.lever)))


def cross3(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """a x b for 3-vectors (np.cross costs ten times as much at this size, every control cycle)."""
    return np.array([a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]])


def gravity_wrench_on_tool(load: ToolLoad, tool_rotation_base: np.ndarray, gravity_base_m_s2: np.ndarray) -> np.ndarray:
    """Wrench (force N, torque N m; tool0 axes, about tool0's origin) that gravity applies on the tool."""
    force_tool = tool_rotation_base.T @ (load.mass_kg * gravity_base_m_s2)
    return np.concatenate([force_tool, cross3(load.com_m, force_tool)])


# ---------------------------------------------------------------------------------------------------
# Wrench conditioning
# ---------------------------------------------------------------------------------------------------
def wrench_fault(wrench: np.ndarray, reject_force_n: float, reject_torque_nm: float) -> str | None:
    """Why a raw sensor wrench must be rejected, or None if it is usable."""
    if wrench.shape != (6,) or not np.all(np.isfinite(wrench)):
        return 'non-finite wrench'
    if np.linalg.norm(wrench[:3]) > reject_force_n or np.linalg.norm(wrench[3:]) > reject_torque_nm:
        return (f'implausible wrench |F| = {np.linalg.norm(wrench[:3]):.3g} N, |T| = {np.linalg.norm(wrench[3:]):.3g} N m '
                f'(rejected above {reject_force_n} N / {reject_torque_nm} N m)')
    return None


def deadband_and_clamp(vector: np.ndarray, deadband: float, limit: float) -> np.ndarray:
    """Shrink the magnitude by `deadband` (zero inside it), then cap it at `limit`; direction kept."""
    magnitude = float(np.linalg.norm(vector))
    if magnitude <= deadband:
        return np.zeros_like(vector)
    return vector * (min(magnitude - deadband, limit) / magnitude)


def lowpass_gain(cutoff_hz: float, interval_s: float) -> float:
    """Blend factor of a first-order low-pass for one sample interval (exact discretisation)."""
    return 1.0 - math.exp(-2.0 * math.pi * cutoff_hz * max(interval_s, 0.0))


class WrenchConditioner:
    """Sensor wrench (tool0) -> hand wrench in base_link axes: gravity, bias, low-pass, deadband, clamp.

    Feed it every sensor sample with `add_sample`, read the conditioned wrench with `output`.
    """

    def __init__(self, config: FdccConfig, load: ToolLoad, gravity_base_m_s2: np.ndarray):
        self.config = config
        self.load = load
        self.gravity_base = np.asarray(gravity_base_m_s2, dtype=float)
        self.bias_tool = np.zeros(6)
        self._recent = collections.deque()    # (time s, gravity-compensated tool wrench)
        self._filtered_base: np.ndarray | None = None
        self._last_sample_time_s: float | None = None

    def add_sample(self, wrench_tool: np.ndarray, tool_rotation_base: np.ndarray, time_s: float) -> None:
        """One valid (already checked with `wrench_fault`) sensor sample at the given time."""
        compensated = np.array(wrench_tool, dtype=float)
        if self.config.gravity_compensation:
            compensated -= gravity_wrench_on_tool(self.load, tool_rotation_base, self.gravity_base)
        self._recent.append((time_s, compensated))
        while self._recent and self._recent[0][0] < time_s - self.config.tare_window_s:
            self._recent.popleft()
        hand_tool = compensated - self.bias_tool
        hand_base = np.concatenate([tool_rotation_base @ hand_tool[:3], tool_rotation_base @ hand_tool[3:]])
        last = self._last_sample_time_s
        if self._filtered_base is None or last is None or time_s - last > self.config.watchdog_timeout_s:
            self._filtered_base = hand_base  # after a gap the old state means nothing
        else:
            gain = lowpass_gain(self.config.lowpass_cutoff_hz, time_s - last)
            self._filtered_base = self._filtered_base + gain * (hand_base - self._filtered_base)
        self._last_sample_time_s = time_s

    def can_tare(self, time_s: float) -> bool:
        """True once the tare window holds samples covering at least half of it, the newest one fresh."""
        if not self._recent:
            return False
        newest, oldest = self._recent[-1][0], self._recent[0][0]
        return time_s - newest <= self.config.watchdog_timeout_s and newest - oldest >= 0.5 * self.config.tare_window_s

    def tare(self) -> np.ndarray:
        """Take the mean gravity-compensated reading of the tare window as the sensor bias."""
        if not self._recent:
            raise RuntimeError('no wrench samples to tare with')
        self.bias_tool = np.mean([w for _, w in self._recent], axis=0)
        self._filtered_base = None  # the filter held the old bias: restart it at the next sample
        return self.bias_tool.copy()

    def output(self) -> np.ndarray:
        """Conditioned hand wrench (force N, torque N m) in base_link axes about the tool0 origin."""
        if self._filtered_base is None:
            return np.zeros(6)
        c = self.config
        return np.concatenate([deadband_and_clamp(self._filtered_base[:3], c.force_deadband_n, c.max_force_n),
                               deadband_and_clamp(self._filtered_base[3:], c.torque_deadband_nm, c.max_torque_nm)])


# ---------------------------------------------------------------------------------------------------
# Joint limits
# ---------------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class JointMotionLimits:
    lower_rad: np.ndarray
    upper_rad: np.ndarray
    velocity_rad_s: np.ndarray
    acceleration_rad_s2: np.ndarray

    @classmethod
    def from_config(cls, config: FdccConfig) -> 'JointMotionLimits':
        urdf = rm.joint_limits()
        margin = config.position_margin_rad
        return cls(lower_rad=urdf.lower_rad + margin, upper_rad=urdf.upper_rad - margin,
                   velocity_rad_s=urdf.velocity_rad_s * config.velocity_limit_scale,
                   acceleration_rad_s2=np.asarray(config.acceleration_limit_rad_s2, dtype=float))


def uniform_scale(vector: np.ndarray, bound: np.ndarray) -> float:
    """Largest factor <= 1 that brings every |vector_i| within bound_i."""
    magnitude = np.abs(vector)
    over = magnitude > bound
    if not np.any(over):
        return 1.0
    return float(np.min(bound[over] / magnitude[over]))


def limit_motion(q: np.ndarray, qdot: np.ndarray, qdot_wanted: np.ndarray, dt_s: float,
                 limits: JointMotionLimits) -> tuple[np.ndarray, np.ndarray]:
    """Next (q, qdot) from the wanted velocity, within acceleration, velocity and position limits."""
    delta = qdot_wanted - qdot
    new_qdot = qdot + uniform_scale(delta, limits.acceleration_rad_s2 * dt_s) * delta
    new_qdot = new_qdot * uniform_scale(new_qdot, limits.velocity_rad_s)
    # Brake towards a position limit so that the acceleration limit can still stop the joint there.
    room = np.where(new_qdot > 0, limits.upper_rad - q, q - limits.lower_rad)
    braking_speed = np.sqrt(2.0 * limits.acceleration_rad_s2 * np.clip(room, 0.0, None))
    new_qdot = np.clip(new_qdot, -braking_speed, braking_speed)
    new_q = q + new_qdot * dt_s
    clipped = np.clip(new_q, limits.lower_rad, limits.upper_rad)
    new_qdot = np.where(clipped != new_q, 0.0, new_qdot)
    return clipped, new_qdot


def decelerate(qdot: np.ndarray, dt_s: float, limits: JointMotionLimits) -> np.ndarray:
    """Joint velocity one step later on a straight-line stop at the acceleration limits."""
    time_to_stop_s = float(np.max(np.abs(qdot) / limits.acceleration_rad_s2))
    if time_to_stop_s <= dt_s:
        return np.zeros_like(qdot)
    return qdot * (1.0 - dt_s / time_to_stop_s)


# ---------------------------------------------------------------------------------------------------
# The solver
# ---------------------------------------------------------------------------------------------------
class FdccSolver:
    """The simulated arm: joint state integrated from forward dynamics under the Cartesian forces."""

    def __init__(self, config: FdccConfig):
        config.validate()
        self.config = config
        self.model = dynamics_model(config)
        self.data = self.model.createData()
        # The control frame is the sensor's: the wrench arrives about tool0's origin.
        self.frame_id = self.model.getFrameId(rm.TOOL_FRAME)
        self.limits = JointMotionLimits.from_config(config)
        self.damping = np.asarray(config.damping, dtype=float)
        self.stiffness = np.asarray(config.stiffness, dtype=float)
        # Fixed by the configuration, so computed here rather than in every control cycle.
        self._joint_damping_matrix = config.joint_damping_nms_per_rad * np.eye(self.model.nv)
        self._max_dt_s = config.max_late_periods * config.nominal_period_s
        self._command_step_rad = self.limits.velocity_rad_s * config.nominal_period_s
        self.q = np.zeros(self.model.nq)
        self.command = np.zeros(self.model.nq)
        self.qdot = np.zeros(self.model.nv)
        self.target_position_m = np.zeros(3)
        self.target_rotation = np.eye(3)

    def reset(self, q: np.ndarray) -> None:
        """Synchronise with the measured arm (at rest); the target pose becomes the current pose."""
        q = np.asarray(q, dtype=float)
        if q.shape != (self.model.nq,) or not np.all(np.isfinite(q)):
            raise ValueError(f'joint positions must be {self.model.nq} finite numbers')
        self.q = np.clip(q, self.limits.lower_rad, self.limits.upper_rad)
        self.command = self.q.copy()
        self.qdot = np.zeros(self.model.nv)
        pose = self.pose(self.q)
        self.target_position_m, self.target_rotation = pose.translation.copy(), pose.rotation.copy()

    def set_target(self, position_m: np.ndarray, rotation: np.ndarray) -> None:
        """Pose of the control frame (base_link) the stiffness K_P pulls towards."""
        position_m, rotation = np.asarray(position_m, float), np.asarray(rotation, float)
        if position_m.shape != (3,) or rotation.shape != (3, 3) or not np.all(np.isfinite(position_m)) \
                or not np.all(np.isfinite(rotation)) or not np.allclose(rotation @ rotation.T, np.eye(3), atol=1e-6):
            raise ValueError('target must be a finite position and a proper rotation')
        self.target_position_m, self.target_rotation = position_m.copy(), rotation.copy()

    def pose(self, q: np.ndarray | None = None) -> pin.SE3:
        """Control frame pose in base_link at q (default: the simulated arm's)."""
        pin.framesForwardKinematics(self.model, self.data, self.q if q is None else q)
        return self.data.oMf[self.frame_id].copy()

    def twist(self) -> np.ndarray:
        """Control frame velocity (linear, angular) in base_link axes."""
        pin.computeJointJacobians(self.model, self.data, self.q)
        jacobian = pin.getFrameJacobian(self.model, self.data, self.frame_id, pin.LOCAL_WORLD_ALIGNED)
        return jacobian @ self.qdot

    def step(self, external_wrench_base: np.ndarray, dt_s: float) -> np.ndarray:
        """Advance the simulated arm by dt under the hand's wrench (base_link axes, about tool0).

        Returns the new joint positions (the command).
        """
        dt = min(float(dt_s), self._max_dt_s)
        if not dt > 0:
            return self.q.copy()
        model, data = self.model, self.data
        q, qdot = self.q, self.qdot
        pin.computeJointJacobians(model, data, q)
        pin.updateFramePlacements(model, data)
        jacobian = pin.getFrameJacobian(model, data, self.frame_id, pin.LOCAL_WORLD_ALIGNED)
        pose = data.oMf[self.frame_id]
        mass_matrix = pin.crba(model, data, q)
        bias_torque = pin.nonLinearEffects(model, data, q, qdot)  # Coriolis and centrifugal; gravity is off
        error = np.concatenate([self.target_position_m - pose.translation,
                                pin.log3(self.target_rotation @ pose.rotation.T)])
        force = np.asarray(external_wrench_base, dtype=float) + self.stiffness * error
        damping_joint = jacobian.T @ (self.damping[:, None] * jacobian)
        stiffness_joint = jacobian.T @ (self.stiffness[:, None] * jacobian)
        lhs = mass_matrix + dt * damping_joint + dt * self._joint_damping_matrix + dt * dt * stiffness_joint
        rhs = mass_matrix @ qdot + dt * (jacobian.T @ force - bias_torque)
        qdot_wanted = np.linalg.solve(lhs, rhs)
        if not np.all(np.isfinite(qdot_wanted)):
            qdot_wanted = np.zeros_like(qdot)  # a numerical failure must not move the arm
        self.q, self.qdot = limit_motion(q, qdot, qdot_wanted, dt, self.limits)
        return self._follow()

    def brake(self, dt_s: float) -> np.ndarray:
        """Decelerate along the current path at the acceleration limits (watchdog); returns the command."""
        dt = min(float(dt_s), self._max_dt_s)
        if dt > 0:
            qdot = decelerate(self.qdot, dt, self.limits)
            self.q, self.qdot = limit_motion(self.q, self.qdot, qdot, dt, self.limits)
        return self._follow()

    def _follow(self) -> np.ndarray:
        """The command: the simulated arm, approached by at most velocity limit x nominal period per cycle.

        Integration uses the real period, so after a late tick the simulated arm may be further on than
        one nominal period at full speed allows; the command then catches up over the next cycles, and
        consecutive commands never imply more than the velocity limit at the nominal rate.
        """
        step = self._command_step_rad
        self.command = self.command + np.clip(self.q - self.command, -step, step)
        return self.command.copy()


# ---------------------------------------------------------------------------------------------------
# The controller the node wires up
# ---------------------------------------------------------------------------------------------------
@dataclass
class TickResult:
    command: np.ndarray | None     # joint positions to publish, None = publish nothing
    state: str                     # 'disabled', 'waiting', 'running', 'holding'


class DragTeachController:
    """Enable/sync, taring, the watchdog and the solver, fed with time-stamped samples (seconds).

    The caller passes every joint state and sensor wrench as it arrives and calls `tick` at the
    control rate; `tick` says what to publish.
    """

    def __init__(self, config: FdccConfig, enabled: bool = True, tare_on_enable: bool = True):
        self.config = config
        self.solver = FdccSolver(config)
        kinematics = rm.pinocchio_model()
        self._kin_model, self._kin_data = kinematics, kinematics.createData()
        self._tool_id = kinematics.getFrameId(rm.TOOL_FRAME)
        self.conditioner = WrenchConditioner(config, tool_load_from_model(kinematics),
                                             np.array(kinematics.gravity.linear))
        self.enabled = enabled
        self.tare_on_enable = tare_on_enable
        self.synced = False
        self._tare_pending = tare_on_enable
        self.measured_q: np.ndarray | None = None
        self._tool_rotation: np.ndarray | None = None
        self._joint_time_s: float | None = None
        self._wrench_time_s: float | None = None
        self._tick_time_s: float | None = None
        self._resumed_s: float | None = 0.0     # when the inputs last became fresh again
        self.rejected_wrenches = 0
        self.rejected_joint_states = 0

    # --- inputs ---
    def on_joint_positions(self, q: np.ndarray, time_s: float) -> str | None:
        """A measured joint state; returns why it was rejected, or None."""
        q = np.asarray(q, dtype=float)
        if q.shape != (rm.NUM_JOINTS,) or not np.all(np.isfinite(q)):
            self.rejected_joint_states += 1
            return 'non-finite or incomplete joint positions'
        self.measured_q = q
        pin.framesForwardKinematics(self._kin_model, self._kin_data, q)
        self._tool_rotation = self._kin_data.oMf[self._tool_id].rotation.copy()
        self._joint_time_s = time_s
        return None

    def on_wrench(self, wrench_tool: np.ndarray, time_s: float) -> str | None:
        """A sensor wrench (force, torque) in tool0; returns why it was rejected, or None."""
        wrench_tool = np.asarray(wrench_tool, dtype=float)
        fault = wrench_fault(wrench_tool, self.config.reject_force_n, self.config.reject_torque_nm)
        if fault is None and self._tool_rotation is None:
            fault = 'no joint state yet: the tool orientation (for gravity compensation) is unknown'
        if fault is not None:
            self.rejected_wrenches += 1
            return fault
        self.conditioner.add_sample(wrench_tool, self._tool_rotation, time_s)
        self._wrench_time_s = time_s
        return None

    # --- commands from outside ---
    def set_enabled(self, enabled: bool) -> None:
        if enabled and not self.enabled:
            self.synced = False               # re-synchronise from the measured joints at the next tick
            self._tare_pending = self.tare_on_enable
        self.enabled = enabled

    def tare(self, time_s: float) -> np.ndarray:
        """Bias = mean gravity-compensated reading over the tare window (raises if there are no fresh samples)."""
        if not self.conditioner.can_tare(time_s):
            raise RuntimeError(f'not enough fresh wrench samples in the last {self.config.tare_window_s} s to tare')
        return self.conditioner.tare()

    def set_target(self, position_m: np.ndarray, rotation: np.ndarray) -> None:
        self.solver.set_target(position_m, rotation)

    # --- the control cycle ---
    def inputs_fresh(self, time_s: float) -> bool:
        timeout = self.config.watchdog_timeout_s
        return (self._joint_time_s is not None and self._wrench_time_s is not None
                and time_s - self._joint_time_s <= timeout and time_s - self._wrench_time_s <= timeout)

    def tick(self, time_s: float) -> TickResult:
        last, self._tick_time_s = self._tick_time_s, time_s
        dt = self.config.nominal_period_s if last is None else time_s - last
        if not self.enabled:
            return TickResult(None, 'disabled')
        if not self.synced:
            if self.measured_q is None or not self.inputs_fresh(time_s):
                return TickResult(None, 'waiting')
            if self._tare_pending:
                if not self.conditioner.can_tare(time_s):
                    return TickResult(None, 'waiting')
                self.conditioner.tare()
                self._tare_pending = False
            self.solver.reset(self.measured_q)
            self.synced = True
            return TickResult(self.solver.q.copy(), 'running')
        if not self.inputs_fresh(time_s):
            self._resumed_s = None
            return TickResult(self.solver.brake(dt), 'holding')
        if self._resumed_s is None:
            self._resumed_s = time_s
        # After a hold the hand may be pushing hard against the stopped arm: fade the wrench back in.
        ramp = min(1.0, (time_s - self._resumed_s) / self.config.resume_ramp_s)
        return TickResult(self.solver.step(ramp * self.conditioner.output(), dt), 'running')


# ---------------------------------------------------------------------------------------------------
# Timing statistics (the node keeps one; the benchmark reads it)
# ---------------------------------------------------------------------------------------------------
class CycleStatistics:
    """The last `window` control cycles: when each tick ran and how long its computation took."""

    def __init__(self, nominal_period_s: float, window: int = 60_000):
        self.nominal_period_s = nominal_period_s
        self.compute_s: collections.deque = collections.deque(maxlen=window)
        self.tick_times_s: collections.deque = collections.deque(maxlen=window)

    def record(self, tick_time_s: float, compute_s: float) -> None:
        self.tick_times_s.append(tick_time_s)
        self.compute_s.append(compute_s)

    def summary(self) -> dict:
        """Compute time mean/p99 (s), achieved rate (Hz) and missed ticks (periods without a tick)."""
        if len(self.tick_times_s) < 2:
            return {'ticks': len(self.tick_times_s)}
        ticks = np.asarray(self.tick_times_s)
        periods = np.diff(ticks)
        missed = int(np.sum(np.maximum(np.round(periods / self.nominal_period_s) - 1, 0)))
        compute = np.asarray(self.compute_s)
        return {'ticks': len(ticks), 'duration_s': float(ticks[-1] - ticks[0]),
                'rate_hz': float((len(ticks) - 1) / (ticks[-1] - ticks[0])), 'missed_ticks': missed,
                'compute_mean_s': float(compute.mean()), 'compute_p99_s': float(np.percentile(compute, 99)),
                'period_p99_s': float(np.percentile(periods, 99))}


# ---------------------------------------------------------------------------------------------------
# Model comparison (`python3 -m stylepong_fdcc.fdcc`): the figures in this module's docstring
# ---------------------------------------------------------------------------------------------------
def simulate_push(config: FdccConfig, q0: np.ndarray, force_base_n: np.ndarray, push_s: float, total_s: float,
                  rate_hz: float) -> dict:
    """Drive the solver alone (a perfect servo) with a constant force at tool0, then nothing."""
    solver = FdccSolver(config)
    solver.reset(q0)
    start = solver.pose().translation.copy()
    dt = 1.0 / rate_hz
    wrench = np.concatenate([np.asarray(force_base_n, dtype=float), np.zeros(3)])
    steps = int(round(total_s * rate_hz))
    push_steps = int(round(push_s * rate_hz))
    positions, speeds, joint_speeds, rotations = [], [], [], []
    for k in range(steps):
        solver.step(wrench if k < push_steps else np.zeros(6), dt)
        pose = solver.pose()
        positions.append(pose.translation.copy())
        rotations.append(pose.rotation.copy())
        speeds.append(solver.twist()[:3].copy())
        joint_speeds.append(np.max(np.abs(solver.qdot)))
    positions, speeds = np.array(positions), np.array(speeds)
    direction = np.asarray(force_base_n) / np.linalg.norm(force_base_n)
    along = speeds @ direction
    steady = along[push_steps - 1]
    rise = int(np.argmax(along >= 0.9 * steady)) + 1
    push_disp = positions[push_steps - 1] - start
    rest = next((k for k in range(push_steps, steps) if joint_speeds[k] < 0.05), steps)
    return {'rise_s': rise * dt, 'push_displacement_m': float(np.linalg.norm(push_disp)),
            'direction_cosine': float(push_disp @ direction / np.linalg.norm(push_disp)),
            'coast_m': float(np.linalg.norm(positions[-1] - positions[push_steps - 1])),
            'rest_after_s': (rest - push_steps + 1) * dt,
            'final_displacement_m': float(np.linalg.norm(positions[-1] - start)),
            'push_rotation_rad': float(np.linalg.norm(pin.log3(rotations[push_steps - 1] @ rotations[0].T)))}


def _compare_models() -> None:
    from stylepong_sim.world_spec import HOME_JOINT_POSITIONS_RAD  # a developer tool: the cell's home pose
    home = np.array(HOME_JOINT_POSITIONS_RAD)
    print('10 N push along +x of base_link for 1 s at 500 Hz, solver alone, home pose')
    for kind in DYNAMICS_MODELS:
        config = FdccConfig(dynamics_model=kind)
        started = time.perf_counter()
        result = simulate_push(config, home, np.array([10.0, 0.0, 0.0]), 1.0, 4.0, 500.0)
        print(f'{kind:8s} ' + ', '.join(f'{k} {v:.3f}' for k, v in result.items())
              + f'  ({time.perf_counter() - started:.1f} s)')


if __name__ == '__main__':
    _compare_models()
