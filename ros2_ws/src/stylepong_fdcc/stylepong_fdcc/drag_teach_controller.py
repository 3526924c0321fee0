"""What `drag_teach` runs each cycle: enable and synchronisation, taring, the watchdog and the solver.

No ROS in here: `drag_teach_node` only wires topics, services and a timer to `DragTeachController`.
- Joint states and wrenches with a non-finite entry are rejected (`wrench_conditioning` says which
  wrenches are implausible) and counted.
- Taring: taken when control is enabled (and at start) and on request (`/drag_teach/tare`).
- Watchdog (docs/DESIGN.md, "FDCC safety layer"): no valid wrench or joint state for
  `watchdog_timeout_s` (50 ms): the simulated arm decelerates at the acceleration limit along its path
  and holds; it resumes when both are fresh, fading the wrench back in over `resume_ramp_s` (a hand
  that kept pushing must not make it lurch).
- The simulated q, qdot are synchronised from the measured joints only when control is (re-)enabled,
  never each cycle: re-syncing would feed the servo's tracking error back in as motion (drift,
  spring-back). While enabled the command is the simulated arm, which is at rest unless pushed.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from stylepong_description import robot_model
from stylepong_fdcc.fdcc_config import FdccConfig
from stylepong_fdcc.fdcc_solver import FdccSolver
from stylepong_fdcc.wrench_conditioning import WrenchConditioner, tool_load_from_model, wrench_fault


@dataclass
class TickResult:
    """One control cycle's outcome: the joint command to publish (if any) and the controller state."""

    command: np.ndarray | None  # joint positions to publish, None = publish nothing
    state: str  # 'disabled', 'waiting', 'running', 'holding'


class DragTeachController:
    """Enable/sync, taring, the watchdog and the solver, fed with time-stamped samples (seconds).

    The caller passes every joint state and sensor wrench as it arrives and calls `tick` at the
    control rate; `tick` says what to publish.
    """

    def __init__(self, config: FdccConfig, enabled: bool = True, tare_on_enable: bool = True):
        self.config = config
        self.solver = FdccSolver(config)
        kinematics = robot_model.pinocchio_model()
        self._kin_model, self._kin_data = kinematics, kinematics.createData()
        self._tool_id = kinematics.getFrameId(robot_model.TOOL_FRAME)
        self.conditioner = WrenchConditioner(
            config, tool_load_from_model(kinematics), np.array(kinematics.gravity.linear)
        )
        self.enabled = enabled
        self.tare_on_enable = tare_on_enable
        self.synced = False
        self._tare_pending = tare_on_enable
        self.measured_q: np.ndarray | None = None
        self._tool_rotation: np.ndarray | None = None
        self._joint_time_s: float | None = None
        self._wrench_time_s: float | None = None
        self._tick_time_s: float | None = None
        self._resumed_s: float | None = 0.0  # when the inputs last became fresh again
        self.rejected_wrenches = 0
        self.rejected_joint_states = 0

    # --- inputs ---
    def on_joint_positions(self, q: np.ndarray, time_s: float) -> str | None:
        """A measured joint state; returns why it was rejected, or None."""
        q = np.asarray(q, dtype=float)
        if q.shape != (robot_model.NUM_JOINTS,) or not np.all(np.isfinite(q)):
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
            self.synced = False  # re-synchronise from the measured joints at the next tick
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
        return (
            self._joint_time_s is not None
            and self._wrench_time_s is not None
            and time_s - self._joint_time_s <= timeout
            and time_s - self._wrench_time_s <= timeout
        )

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
