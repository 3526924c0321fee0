"""What both cells (MuJoCo `cell.Cell`, PyBullet `bullet_cell.BulletCell`) do alike, free of ROS and of physics:
the checks on every command, the ball's launch and removal as the referee sees them, the hand on the tool, the
referee's verdict after a ball step and the getters of the API that cell.py's docstring states.

A cell derives from CellBase and supplies its engine's side (the abstract methods below): its clock, the
paddle's and the tool's poses, putting the robot home, one physics step, the engine's ball appearing and going,
the command reaching its actuator model, and a wrench pushing on the tool. This module imports neither
ball_contacts nor batched_world: the PyBullet cell, which derives from it, must load nothing of the analytic
ball contacts.
"""

from __future__ import annotations

import abc
import math
from dataclasses import dataclass

import numpy as np

from stylepong_description import robot_model
from stylepong_sim import referee, world_spec
from stylepong_sim.cells import ur_servoj
from stylepong_sim.cells.cell_inputs import FRAME_TOOL, FRAME_WORLD, MAX_LAUNCH_SPEED_M_S, InputError


@dataclass
class HandWrench:
    """A hand on the tool: force and torque at tool0's origin, in tool0's axes or the world's, until a time."""

    force_n: np.ndarray
    torque_nm: np.ndarray
    in_tool_frame: bool
    release_time_s: float


def checked_actuator(actuator: str) -> str:
    """`actuator` if it names one of ur_servoj's actuator models; ValueError otherwise."""
    if actuator not in ur_servoj.ACTUATORS:
        raise ValueError(f'actuator must be one of {", ".join(ur_servoj.ACTUATORS)}, got {actuator!r}')
    return actuator


def checked_ball_launch(position_m, velocity_m_s) -> tuple[np.ndarray, np.ndarray]:
    """The launch's position and velocity as own 3-vectors; InputError if not finite, faster than
    MAX_LAUNCH_SPEED_M_S or where the referee would call the ball dead at once."""
    position = np.array(position_m, dtype=float).reshape(3)
    velocity = np.array(velocity_m_s, dtype=float).reshape(3)
    if not (np.isfinite(position).all() and np.isfinite(velocity).all()):
        raise InputError('not_finite', 'ball position and velocity must be finite')
    speed = np.linalg.norm(velocity)
    if speed > MAX_LAUNCH_SPEED_M_S:
        raise InputError('speed', f'ball speed {speed:.2f} m/s exceeds {MAX_LAUNCH_SPEED_M_S} m/s')
    if referee.ball_is_dead(position):
        raise InputError('position', f'ball position {position.tolist()} is outside the cell (or below the floor)')
    return position, velocity


def checked_hand_wrench(force_n, torque_nm, frame: str, duration_s: float, time_s: float) -> HandWrench:
    """The hand wrench set at time_s for duration_s; InputError if not finite, in an unknown frame or not
    lasting."""
    force = np.array(force_n, dtype=float).reshape(3)
    torque = np.array(torque_nm, dtype=float).reshape(3)
    if not (np.isfinite(force).all() and np.isfinite(torque).all()):
        raise InputError('not_finite', f'hand wrench must be finite, got {force.tolist()} {torque.tolist()}')
    if frame not in (FRAME_WORLD, FRAME_TOOL):
        raise InputError('frame', f"hand wrench frame must be '{FRAME_WORLD}' or '{FRAME_TOOL}', not '{frame}'")
    if not duration_s > 0.0:
        raise InputError('duration', 'hand wrench duration must be positive')
    return HandWrench(force, torque, frame == FRAME_TOOL, time_s + duration_s)


class CellBase(abc.ABC):
    """The engine-free half of a cell: inputs, ball bookkeeping, referee events, hand wrench, getters."""

    def __init__(self, home_joint_positions_rad, actuator: str, dt_s: float):
        self.actuator = checked_actuator(actuator)
        self._dt = dt_s
        self._joint_limits = robot_model.joint_limits()
        self._lower_rad = self._joint_limits.lower_rad.copy()
        self._upper_rad = self._joint_limits.upper_rad.copy()
        self.home_joint_positions_rad = self._checked_joint_vector(home_joint_positions_rad, 'home pose')
        self._q_cmd = self.home_joint_positions_rad.copy()
        self._referee = referee.Referee()
        self._events: list[referee.RallyEvent] = []
        self._next_ball_id = 1
        self.ball_id: int | None = None
        self._ball_p = np.zeros(3)
        self._ball_v = np.zeros(3)
        self._ball_launch_time_s = 0.0
        self._hand: HandWrench | None = None

    # --- the engine's side -----------------------------------------------------------------------
    @property
    @abc.abstractmethod
    def time_s(self) -> float:
        """Simulated time since the cell was made."""

    @abc.abstractmethod
    def paddle_pose(self) -> tuple[np.ndarray, np.ndarray]:
        """The blade centre's position and rotation (columns: its axes in world)."""

    @abc.abstractmethod
    def tool_pose(self) -> tuple[np.ndarray, np.ndarray]:
        """tool0's position and rotation (columns: its axes in world)."""

    @abc.abstractmethod
    def _reset_robot(self) -> None:
        """The arm at home and at rest, its target and actuator model there too."""

    @abc.abstractmethod
    def _step_once(self) -> None:
        """One physics step of dt_s: arm, hand, ball, and the referee told what happened."""

    @abc.abstractmethod
    def _command_reference(self, q_rad: np.ndarray) -> None:
        """Hand a checked joint target to the actuator model."""

    @abc.abstractmethod
    def _start_ball(self) -> None:
        """The engine's ball at _ball_p with _ball_v (the bookkeeping is done)."""

    @abc.abstractmethod
    def _drop_ball(self) -> None:
        """The engine's ball gone (the referee has been told)."""

    @abc.abstractmethod
    def _push_on_tool(self, force_n: np.ndarray, torque_nm: np.ndarray) -> None:
        """Apply a wrench at tool0's origin, world axes, for the coming step."""

    # --- commands --------------------------------------------------------------------------------
    def reset(self) -> None:
        self.remove_ball()
        self.clear_hand_wrench()
        self._reset_robot()

    def set_joint_targets(self, q_rad) -> None:
        self._q_cmd = self._checked_joint_vector(q_rad, 'joint target')
        self._command_reference(self._q_cmd)

    @property
    def joint_targets_rad(self) -> np.ndarray:
        """The last target accepted by set_joint_targets (home after a reset)."""
        return self._q_cmd.copy()

    def set_hand_wrench(
        self, force_n, torque_nm=(0.0, 0.0, 0.0), frame: str = FRAME_WORLD, duration_s: float = math.inf
    ) -> None:
        self._hand = checked_hand_wrench(force_n, torque_nm, frame, duration_s, self.time_s)

    def clear_hand_wrench(self) -> None:
        self._hand = None

    def launch_ball(self, position_m, velocity_m_s) -> int:
        position, velocity = checked_ball_launch(position_m, velocity_m_s)
        self.remove_ball()
        self.ball_id = self._next_ball_id
        self._next_ball_id += 1
        self._ball_p, self._ball_v = position, velocity
        self._ball_launch_time_s = self.time_s
        self._start_ball()
        self._events += self._referee.launch(self.ball_id, self.time_s, position)
        return self.ball_id

    def remove_ball(self) -> None:
        if self.ball_id is None:
            return
        self._events += self._referee.abort(self.time_s, self._ball_p)
        self.ball_id = None
        self._drop_ball()

    # --- stepping --------------------------------------------------------------------------------
    @property
    def dt_s(self) -> float:
        return self._dt

    def step(self, n_steps: int = 1) -> None:
        for _ in range(n_steps):
            self._step_once()

    def step_for(self, duration_s: float) -> None:
        """As many steps of dt_s as come nearest to duration_s."""
        self.step(max(0, round(duration_s / self._dt)))

    # --- state -----------------------------------------------------------------------------------
    @property
    def ball_in_play(self) -> bool:
        return self.ball_id is not None

    @property
    def ball_position_m(self) -> np.ndarray | None:
        return self._ball_p.copy() if self.ball_id is not None else None

    @property
    def ball_velocity_m_s(self) -> np.ndarray | None:
        return self._ball_v.copy() if self.ball_id is not None else None

    def pop_events(self) -> list[referee.RallyEvent]:
        events, self._events = self._events, []
        return events

    # --- internals -------------------------------------------------------------------------------
    def _checked_joint_vector(self, q_rad, what: str) -> np.ndarray:
        q = np.asarray(q_rad, dtype=float)
        if q.shape != (6,):
            raise InputError('length', f'{what} needs 6 joint positions, got shape {q.shape}')
        if not np.isfinite(q).all():
            raise InputError('not_finite', f'{what} contains NaN or inf: {q.tolist()}')
        outside = (q < self._lower_rad) | (q > self._upper_rad)
        if outside.any():
            names = [robot_model.JOINT_NAMES[i] for i in np.flatnonzero(outside)]
            raise InputError('limits', f'{what} outside the joint limits at {names}: {q.tolist()}')
        return q.copy()

    def _hand_in_world(self) -> tuple[np.ndarray, np.ndarray]:
        """The hand's force and torque in world axes (a tool-frame hand turns with the tool)."""
        hand = self._hand
        if not hand.in_tool_frame:
            return hand.force_n, hand.torque_nm
        _, rotation = self.tool_pose()
        return rotation @ hand.force_n, rotation @ hand.torque_nm

    def _apply_hand_wrench(self) -> None:
        """Before a step: the hand pushes on the tool, or lets go once its time is up."""
        if self.time_s >= self._hand.release_time_s:
            self.clear_hand_wrench()
            return
        self._push_on_tool(*self._hand_in_world())

    def _judge_ball(self, time_s: float) -> None:
        """After the ball's step: the referee sees its state while the rally is open; once it has ruled, the
        ball goes when dead or BALL_LIFETIME_S after its launch."""
        if self._referee.rally_open:
            self._events += self._referee.ball_state(time_s, self._ball_p, self._ball_v)
        elif referee.ball_is_dead(self._ball_p) or time_s - self._ball_launch_time_s >= world_spec.BALL_LIFETIME_S:
            self.remove_ball()
