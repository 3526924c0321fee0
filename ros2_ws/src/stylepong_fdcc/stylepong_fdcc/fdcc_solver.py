"""The FDCC solver: the simulated arm that the hand drags (Forward Dynamics Compliance Control,
Scherzinger et al. 2017). No ROS in here: `drag_teach_controller` feeds it, `drag_teach_node` wires that up.

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

    solver alone, a perfect servo (`python3 -m stylepong_fdcc.compare_dynamics_models`):
    model    rise to 90 % speed   moved during the push   coasts after release   at rest after release
    virtual        0.12 s               0.306 m                 0.023 m                 0.19 s
    urdf           0.64 s               0.225 m                 0.102 m                 1.19 s
    through the MuJoCo cell (stylepong_sim.cells.cell: servo, F/T sensor; 4 ms transport each way):
    virtual        0.10 s               0.277 m                 0.020 m                 0.14 s
    urdf           0.55 s               0.198 m                 0.094 m                 0.99 s

Both end 0.29-0.33 m along +x (impulse / damping, direction cosine 0.9999). The URDF model feels like
its mass: its effective mass at the tool is 4.0-10.7 kg depending on direction (1.1-1.3 kg for the
virtual model), so the arm lags the hand for half a second, and after the hand lets go it carries on
for another 10 cm and a second. The virtual model follows the hand within a tenth of a second and
stops where the hand stops, which is what a person dragging it expects, so it is the default.

Safety in the solver (docs/DESIGN.md, "FDCC safety layer"): joint motion is limited by `joint_limits`;
a command never moves a joint more than its velocity limit times the nominal period from the previous
one, even after a late tick (the command then catches up with the simulated arm over the next cycles);
a stall longer than `max_late_periods` control periods is integrated as that many, so the arm carries
on instead of jumping.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from stylepong_description import robot_model
from stylepong_fdcc.fdcc_config import FdccConfig
from stylepong_fdcc.joint_limits import command_limits, decelerate, limit_motion


def dynamics_model(config: FdccConfig) -> pin.Model:
    """The gravity-free model the solver integrates: the URDF's inertias, or FZI-style light links."""
    model = robot_model.pinocchio_model()
    model.gravity = pin.Motion.Zero()
    if config.dynamics_model == 'virtual':
        last = model.njoints - 1
        for joint in range(1, model.njoints):
            mass, inertia = (
                (config.virtual_end_mass_kg, config.virtual_end_inertia_kg_m2)
                if joint == last
                else (config.virtual_link_mass_kg, config.virtual_link_inertia_kg_m2)
            )
            model.inertias[joint] = pin.Inertia(mass, np.zeros(3), inertia * np.eye(3))
    return model


class FdccSolver:
    """The simulated arm: joint state integrated from forward dynamics under the Cartesian forces."""

    def __init__(self, config: FdccConfig):
        config.validate()
        self.config = config
        self.model = dynamics_model(config)
        self.data = self.model.createData()
        # The control frame is the sensor's: the wrench arrives about tool0's origin.
        self.frame_id = self.model.getFrameId(robot_model.TOOL_FRAME)
        self.limits = command_limits(config)
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
        if (
            position_m.shape != (3,)
            or rotation.shape != (3, 3)
            or not np.all(np.isfinite(position_m))
            or not np.all(np.isfinite(rotation))
            or not np.allclose(rotation @ rotation.T, np.eye(3), atol=1e-6)
        ):
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
        error = np.concatenate(
            [self.target_position_m - pose.translation, pin.log3(self.target_rotation @ pose.rotation.T)]
        )
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
