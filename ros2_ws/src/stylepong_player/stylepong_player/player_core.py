"""The 60 Hz player without ROS: checks inputs, runs the actor, limits every command, keeps statistics.

player_node.py wires this to topics; tests drive it directly with made-up times and messages.

States
  disabled  publishes nothing (start-up, or /player/enable false)
  ready     moves the arm to home at a gentle speed (home_speed_rad_s, home_acceleration_rad_s2), then holds
  playing   while a fresh ball is in play: observation (spec.build_observation, on numpy arrays) -> actor ->
            joint position targets (spec's decoding) -> limiter; back to ready when no ball message has
            been accepted for ball_timeout_s (the ball is gone, or the camera lost it)
No command at all while the joint states are stale (none accepted for joint_timeout_periods periods):
ros2_control's forward_position_controller then holds its last target, which is the safe thing. A command
more than joint_timeout_periods after the previous one starts again from the measured position, at rest;
one sooner continues the previous segment, so consecutive commands always keep the limits.

Timing (the actor was trained with at most 1/60 s between observation and actuation and breaks when
actuation timing drifts): while playing, policy steps keep a 60 Hz grid on the node's clock, anchored at
the first one. A ball message that arrives within STEP_TOLERANCE_PERIODS of a grid point drives that step
at once (the freshest ball: with a 120 Hz tracker every second frame, so the grid locks to its phase);
if none has come STEP_TOLERANCE_PERIODS after it (a lost frame, a tracker whose rate is no multiple of
60 Hz such as 150 Hz), the step runs on the latest ball, carried forward to the step (checked at every
joint state). Ready moves, where nothing is fast, run on a plain 60 Hz timer.

Every command passes CommandLimiter: within the URDF position limits less a margin, at most the velocity
limit per period and the acceleration limit, braking early enough that the position limits hold without
ever exceeding the acceleration limit. With stream_commands (the default) the node publishes the limited
commands as a stream (CommandStream): on every joint state, the point on the straight path from where the
stream was to the latest command, reached one period after its step, so the arm's controller samples a
ramp at its own rate instead of a step every period. Messages with NaN/inf, the wrong length or joint names, the wrong
frame, implausible values or stamps are rejected (counted, a throttled warning in the node) and never
reach the actor.
"""

from __future__ import annotations

import collections
import enum
import math
import pathlib
import time
import warnings
from dataclasses import dataclass
from typing import Callable, Sequence

import numpy as np

from stylepong_description import robot_cell
from stylepong_description.robot_cell import FRAME_WORLD
from stylepong_description.robot_model import JointLimits
from stylepong_player import spec
from stylepong_player.actor_contract import (
    ONNX_INPUT,
    ONNX_OUTPUT,
    ActorMismatchError,
    check_contract,
    onnx_path,
    parse_onnx_metadata,
    read_sidecar,
)
from stylepong_player.ball_prediction import predict_ball

# A ball message arriving this close (in periods) to a step's grid point drives the step; none by this
# long after it: the step runs on the latest ball. Small, so that steps stay within a few milliseconds of
# the 60 Hz the actor was trained at whatever the tracker's rate: stepping on the first frame a quarter
# period early ran a 150 Hz tracker's steps 13 and 20 ms apart, and stepping only a period after the last
# step let the 20 ms gaps fall to the fallback. A ball a frame older costs nothing: it is carried forward.
STEP_TOLERANCE_PERIODS = 0.1
# Steps closer together than this are refused: a step that ran late (its ball was late) is not followed at
# once by the next grid point's.
MIN_STEP_SPACING_PERIODS = 0.5
# Measured joints may lie a little outside the URDF limits (encoder noise, a controller's overshoot).
JOINT_POSITION_TOLERANCE_RAD = 0.05
JOINT_VELOCITY_FACTOR = 2.0
STATS_WINDOW = 4096
ARRIVAL_TOLERANCE_S = 1e-9  # a stream segment has ended (times are sums of floats)


# --- limits and the command limiter ------------------------------------------------------------------
def stopping_speed(distance_rad: np.ndarray, acceleration_rad_s2: np.ndarray, period_s: float) -> np.ndarray:
    """The largest speed per period from which CommandLimiter can stop within `distance_rad`.

    The limiter moves x += v * T and changes v by at most a T per period, so from speed v = m u
    (u = a T) it stops after the distance T (v + (v - u) + (v - 2u) + ...) over the positive terms. For
    n positive terms and v in ((n-1) u, n u] that is T (n v - u n (n-1) / 2): solved here for v.
    Consistent by construction: from the largest allowed v, the next period's bound is at least v - u.
    """
    d = np.maximum(np.asarray(distance_rad, dtype=float), 0.0)
    u = acceleration_rad_s2 * period_s
    steps = d / period_s / u  # distance in units of u T
    n = np.maximum(np.ceil((-1.0 + np.sqrt(1.0 + 8.0 * steps)) / 2.0), 1.0)
    return (d / period_s + u * n * (n - 1.0) / 2.0) / n


class CommandLimiter:
    """Turns targets into commands within position, velocity-per-period and acceleration limits.

    A command segment starts (`start`) at rest at a measured position; each `step` moves toward the
    target as fast as the limits allow, braking so that it stops at the target (no overshoot unless the
    target jumps closer than the braking distance) and always before a position limit.
    """

    def __init__(self, limits: JointLimits, period_s: float):
        self.limits = limits
        self.period_s = period_s
        self.position_rad: np.ndarray | None = None
        self.velocity_rad_s = np.zeros(len(limits.lower_rad))

    @property
    def active(self) -> bool:
        return self.position_rad is not None

    def start(self, position_rad: np.ndarray) -> None:
        self.position_rad = np.clip(np.asarray(position_rad, dtype=float), self.limits.lower_rad, self.limits.upper_rad)
        self.velocity_rad_s = np.zeros_like(self.position_rad)

    def stop(self) -> None:
        self.position_rad = None

    def step(
        self, target_rad: np.ndarray, max_speed_rad_s: float | None = None, max_acceleration_rad_s2: float | None = None
    ) -> np.ndarray:
        """The next command toward `target_rad` (optionally slower than the limits: home moves)."""
        lim = self.limits
        dt = self.period_s
        x, v_prev = self.position_rad, self.velocity_rad_s
        v_max = lim.velocity_rad_s if max_speed_rad_s is None else np.minimum(lim.velocity_rad_s, max_speed_rad_s)
        a_max = (
            lim.acceleration_rad_s2
            if max_acceleration_rad_s2 is None
            else np.minimum(lim.acceleration_rad_s2, max_acceleration_rad_s2)
        )
        target = np.clip(np.where(np.isfinite(target_rad), target_rad, x), lim.lower_rad, lim.upper_rad)
        to_target = target - x
        # Wanted: reach the target, but no faster than what still stops there.
        wanted = np.clip(to_target / dt, -stopping_speed(-to_target, a_max, dt), stopping_speed(to_target, a_max, dt))
        # Hard: the acceleration window, the speed limit and braking before the position limits. The three
        # intervals intersect pairwise (the previous step kept the braking bound), hence all together.
        low = np.maximum(np.maximum(v_prev - a_max * dt, -v_max), -stopping_speed(x - lim.lower_rad, a_max, dt))
        high = np.minimum(np.minimum(v_prev + a_max * dt, v_max), stopping_speed(lim.upper_rad - x, a_max, dt))
        v = np.clip(wanted, low, np.maximum(low, high))
        command = np.clip(x + v * dt, lim.lower_rad, lim.upper_rad)
        self.velocity_rad_s = (command - x) / dt
        self.position_rad = command
        return command.copy()


class CommandStream:
    """The limiter's commands, one per period, as a stream of points at the controller's rate.

    Each new command starts a segment from the point the stream is at to the command, travelled at constant
    speed over one period (longer if a joint would exceed its velocity limit: a command that comes while the
    previous segment is unfinished); `point(now)` is where the segment is at `now`, held at its end once
    there. Why: a position-controlled joint fed a step every 1/60 s moves in dashes (the ideal servo
    reference runs at full speed to each step, then waits; a stiff drive follows it and saturates its
    torques), where a UR controller at 125-500 Hz fed the same path as a ramp moves smoothly. Points lie on
    segments between commands, so the limiter's position limits hold for every point, and its velocity
    limits for every segment.
    """

    def __init__(self, velocity_limit_rad_s: np.ndarray, period_s: float):
        self.velocity_limit_rad_s = np.asarray(velocity_limit_rad_s, dtype=float)
        self.period_s = period_s
        self._start_rad: np.ndarray | None = None
        self._end_rad: np.ndarray | None = None
        self._start_s = -math.inf
        self._duration_s = period_s

    @property
    def active(self) -> bool:
        return self._end_rad is not None

    def start(self, position_rad: np.ndarray) -> None:
        """At rest at position_rad (a restart from the measured joints)."""
        self._start_rad = np.array(position_rad, dtype=float)
        self._end_rad = self._start_rad.copy()
        self._start_s, self._duration_s = -math.inf, self.period_s

    def stop(self) -> None:
        self._start_rad = self._end_rad = None

    def aim(self, command_rad: np.ndarray, now_s: float) -> np.ndarray:
        """A new segment from the point at now_s to command_rad; that point (where the segment starts)."""
        origin = self.point(now_s)
        target = np.array(command_rad, dtype=float)
        shortest_s = float(np.max(np.abs(target - origin) / self.velocity_limit_rad_s))
        self._start_rad, self._end_rad = origin, target
        self._start_s, self._duration_s = now_s, max(self.period_s, shortest_s)
        return origin.copy()

    def point(self, now_s: float) -> np.ndarray:
        """The stream's point at now_s."""
        if self.arrived(now_s):
            return self._end_rad.copy()
        fraction = max((now_s - self._start_s) / self._duration_s, 0.0)
        return self._start_rad + fraction * (self._end_rad - self._start_rad)

    def arrived(self, now_s: float) -> bool:
        return now_s - self._start_s >= self._duration_s - ARRIVAL_TOLERANCE_S


# --- observation and action ---------------------------------------------------------------------------
# The observation is spec.build_observation's and the action's decoding spec.decode_action's, on numpy arrays.
_HOME = np.asarray(spec.HOME_JOINT_POSITIONS_RAD, dtype=np.float64)


def build_observation(
    q_rad: np.ndarray,
    qd_rad_s: np.ndarray,
    ball_position_m: np.ndarray,
    ball_velocity_m_s: np.ndarray,
    goal_xy_m: np.ndarray,
    last_action: np.ndarray,
) -> np.ndarray:
    """The actor's observation [1, NUM_OBS] float32 (joints in URDF order): spec.build_observation on one row."""
    parts = (q_rad, qd_rad_s, ball_position_m, ball_velocity_m_s, goal_xy_m, last_action)
    for (name, size), part in zip(spec.OBS_LAYOUT, parts):
        if np.shape(part) != (size,):
            raise ValueError(f'{name} needs {size} values, got shape {np.shape(part)}')
    return spec.build_observation(*(np.asarray(part, dtype=np.float32)[None, :] for part in parts))


class JointOrder:
    """Indices of spec.JOINT_NAMES in a JointState's name list, remembered for the last list seen."""

    def __init__(self):
        self._names: tuple[str, ...] = ()
        self._index: np.ndarray | None = None

    def index(self, names: Sequence[str]) -> np.ndarray | None:
        names = tuple(names)
        if names != self._names:
            position = {name: i for i, name in enumerate(names)}
            self._index = (
                np.array([position[n] for n in spec.JOINT_NAMES])
                if all(n in position for n in spec.JOINT_NAMES)
                else None
            )
            self._names = names
        return self._index


# --- actors ------------------------------------------------------------------------------------------
class OnnxActor:
    """The exported `<name>.onnx` in onnxruntime, one thread (a 2-core robot computer runs more than this)."""

    backend = 'onnx'

    def __init__(self, path: str | pathlib.Path, expected: dict | None = None):
        import onnxruntime

        self.path = pathlib.Path(path)
        if not self.path.is_file():
            raise ActorMismatchError(f'actor file {self.path} does not exist')
        options = onnxruntime.SessionOptions()
        options.intra_op_num_threads = 1
        options.inter_op_num_threads = 1
        options.execution_mode = onnxruntime.ExecutionMode.ORT_SEQUENTIAL
        try:
            self._session = onnxruntime.InferenceSession(str(self.path), options, providers=['CPUExecutionProvider'])
        except Exception as error:  # noqa: BLE001 - onnxruntime raises its own classes for damaged files
            raise ActorMismatchError(f'{self.path} is not a loadable ONNX model: {error}') from error
        props = self._session.get_modelmeta().custom_metadata_map
        self.metadata = parse_onnx_metadata(dict(props), self.path)
        check_contract(self.metadata, self.path, expected)
        inputs, outputs = self._session.get_inputs(), self._session.get_outputs()
        if [i.name for i in inputs] != [ONNX_INPUT] or [o.name for o in outputs] != [ONNX_OUTPUT]:
            raise ActorMismatchError(
                f'{self.path} has inputs {[i.name for i in inputs]} and outputs '
                f'{[o.name for o in outputs]}, expected [{ONNX_INPUT!r}] and [{ONNX_OUTPUT!r}]'
            )
        check_output_shape(self)

    def __call__(self, obs: np.ndarray) -> np.ndarray:
        return self._session.run([ONNX_OUTPUT], {ONNX_INPUT: obs})[0]


class TorchScriptActor:
    """The exported `<name>.pt` with its sidecar, in torch (one thread, inference mode)."""

    backend = 'torchscript'

    def __init__(self, path: str | pathlib.Path, expected: dict | None = None):
        import torch

        torch.set_num_threads(1)
        self._torch = torch
        self.path = pathlib.Path(path)
        self.metadata = read_sidecar(self.path, expected)
        with warnings.catch_warnings():
            # torch flags torch.jit as deprecated; TorchScript is still what loads an actor in one call.
            warnings.filterwarnings('ignore', message=r'`torch\.jit\.', category=DeprecationWarning)
            self._module = torch.jit.load(str(self.path), map_location='cpu').eval()
        check_output_shape(self)

    def __call__(self, obs: np.ndarray) -> np.ndarray:
        with self._torch.inference_mode():
            return self._module(self._torch.from_numpy(obs)).numpy()


def check_output_shape(actor) -> None:
    """ActorMismatchError unless the actor maps one observation row to one action row, as its contract says."""
    out = actor(np.zeros((1, int(actor.metadata['num_obs'])), dtype=np.float32))
    if tuple(out.shape) != (1, int(actor.metadata['num_actions'])):
        raise ActorMismatchError(
            f'{actor.path} outputs shape {tuple(out.shape)}, its contract promises (1, {actor.metadata["num_actions"]})'
        )


BACKENDS = ('onnx', 'torchscript')


def load_actor(path: str | pathlib.Path, backend: str, expected: dict | None = None):
    """The actor of an export (`<name>.pt` or `<name>.onnx`: the file of `backend` beside it is used)."""
    path = pathlib.Path(path)
    if backend == 'onnx':
        return OnnxActor(onnx_path(path), expected)
    if backend == 'torchscript':
        return TorchScriptActor(path.with_suffix('.pt'), expected)
    raise ValueError(f'backend must be one of {BACKENDS}, got {backend!r}')


# --- statistics --------------------------------------------------------------------------------------
class Samples:
    """The last STATS_WINDOW values of one measurement, and how many there were in all."""

    def __init__(self):
        self.values: collections.deque[float] = collections.deque(maxlen=STATS_WINDOW)
        self.count = 0
        self.max = -math.inf

    def add(self, value: float) -> None:
        self.values.append(value)
        self.count += 1
        self.max = max(self.max, value)

    def summary(self, scale: float = 1e3) -> dict:
        """count, p50, p99, max (of the window; max_ever over all), in ms by default."""
        if not self.values:
            return {'count': 0}
        v = np.fromiter(self.values, dtype=float) * scale
        return {
            'count': self.count,
            'mean': round(float(v.mean()), 4),
            'p50': round(float(np.percentile(v, 50)), 4),
            'p99': round(float(np.percentile(v, 99)), 4),
            'max': round(float(v.max()), 4),
            'max_ever': round(self.max * scale, 4),
        }


# --- the player --------------------------------------------------------------------------------------
@dataclass(frozen=True)
class PlayerConfig:
    """The player's settings: rate, goal, command limits, homing and input timeouts."""

    rate_hz: float = spec.ACTION_RATE_HZ
    goal_xy_m: tuple[float, float] = (0.685, 0.0)
    position_margin_rad: float = 0.02
    velocity_limit_scale: float = 1.0
    acceleration_limit_rad_s2: tuple[float, ...] = (400.0,) * spec.NUM_ACTIONS
    home_speed_rad_s: float = 1.0
    home_acceleration_rad_s2: float = 4.0
    home_tolerance_rad: float = 0.01
    joint_timeout_periods: float = 3.0
    # Six periods, the estimator's own track timeout: a few lost frames, a moment of a busy computer or the four
    # frames the estimator takes to follow the paddle's hit must not end a stroke (the ball is carried forward).
    ball_timeout_s: float = 0.1
    max_ball_age_s: float = 0.2
    max_ball_speed_m_s: float = 30.0
    max_ball_velocity_std_m_s: float = 1.0
    stream_commands: bool = True
    predict_ball: bool = True

    @property
    def period_s(self) -> float:
        return 1.0 / self.rate_hz

    def validate(self) -> None:
        if not math.isclose(self.rate_hz, spec.ACTION_RATE_HZ):
            raise ValueError(f"rate_hz must be the actor's action rate {spec.ACTION_RATE_HZ} Hz, got {self.rate_hz}")
        if len(self.acceleration_limit_rad_s2) != spec.NUM_ACTIONS:
            raise ValueError(f'acceleration_limit_rad_s2 needs {spec.NUM_ACTIONS} values')
        check_goal(self.goal_xy_m)


def check_goal(goal_xy_m: Sequence[float]) -> None:
    """ValueError unless the goal is a finite point on the opponent's half (x > 0)."""
    x, y = (float(v) for v in goal_xy_m)
    half_length_m, half_width_m = robot_cell.HALF_LENGTH_M, robot_cell.HALF_WIDTH_M
    if not (math.isfinite(x) and math.isfinite(y) and 0.0 < x <= half_length_m and abs(y) <= half_width_m):
        raise ValueError(
            f"goal ({x}, {y}) m is not on the opponent's half "
            f'(0 < x <= {robot_cell.HALF_LENGTH_M}, |y| <= {robot_cell.HALF_WIDTH_M})'
        )


class State(str, enum.Enum):
    """The player's state: disabled, ready (at home) or playing."""

    DISABLED = 'disabled'
    READY = 'ready'
    PLAYING = 'playing'


@dataclass
class StepResult:
    """One player step: the command (None: none), the state, whether the actor ran, and why no command."""

    command: np.ndarray | None
    state: State
    policy: bool = False  # the actor ran
    problem: str = ''  # why there is no command ('' when there is one, or when disabled)


@dataclass
class _Ball:
    position_m: np.ndarray
    velocity_m_s: np.ndarray
    stamp_s: float
    received_s: float


class Player:
    """The player's logic; the caller supplies times (the node's clock, seconds) and calls `step` when
    `ball_step_due` / `fallback_step_due` / `timer_step_due` say so."""

    def __init__(
        self,
        config: PlayerConfig,
        actor: Callable[[np.ndarray], np.ndarray],
        *,
        perf_counter: Callable[[], float] = time.perf_counter,
    ):
        config.validate()
        self.config = config
        self.actor = actor
        self.period_s = config.period_s
        self.limits = JointLimits.for_commands(
            config.position_margin_rad, config.velocity_limit_scale, config.acceleration_limit_rad_s2
        )
        self.limiter = CommandLimiter(self.limits, self.period_s)
        self.stream = CommandStream(self.limits.velocity_rad_s, self.period_s) if config.stream_commands else None
        self._stream_at_end = True  # the stream's last point has been handed out
        self.state = State.DISABLED
        self.goal_xy_m = np.asarray(config.goal_xy_m, dtype=np.float32)
        self.last_action = np.zeros(spec.NUM_ACTIONS, dtype=np.float32)
        self._perf_counter = perf_counter
        self._joint_order = JointOrder()
        self._q: np.ndarray | None = None
        self._qd: np.ndarray | None = None
        self._joint_received_s = -math.inf
        self._ball: _Ball | None = None
        self._grid_s = -math.inf  # the next policy step's place on the 60 Hz grid (node clock)
        self._last_step_s = -math.inf
        self._last_command_s = -math.inf
        self._last_command_wall_s = -math.inf
        # Measured positions are checked against the URDF limits themselves (commands keep a margin inside).
        self._urdf_lower = self.limits.lower_rad - config.position_margin_rad - JOINT_POSITION_TOLERANCE_RAD
        self._urdf_upper = self.limits.upper_rad + config.position_margin_rad + JOINT_POSITION_TOLERANCE_RAD
        self._max_joint_speed = self.limits.velocity_rad_s / config.velocity_limit_scale * JOINT_VELOCITY_FACTOR
        self.rejected: dict[str, int] = collections.defaultdict(int)
        self.period = Samples()  # between consecutive policy steps (playing), node clock
        self.period_wall = Samples()  # the same on the wall clock (monotonic)
        self.period_ready = Samples()  # between consecutive home moves (ready, the 60 Hz timer)
        self.latency = Samples()  # ball stamp -> command published, ball-driven steps, node clock
        self.receipt_latency = Samples()  # ball message's callback -> command published, wall clock
        self.fallback_ball_age = Samples()  # age of the ball a fallback step used, node clock
        self.inference = Samples()  # actor call
        self.counts: dict[str, int] = collections.defaultdict(int)
        self._last_state_for_period = State.DISABLED

    # --- inputs ------------------------------------------------------------------------------------
    def _reject(self, kind: str, reason: str) -> str:
        self.rejected[kind] += 1
        return reason

    def set_enabled(self, enabled: bool) -> None:
        if enabled and self.state == State.DISABLED:
            self.state = State.READY
            self._stop_commands()  # the next command starts from the measured position
        elif not enabled:
            self.state = State.DISABLED
            self._stop_commands()

    def _stop_commands(self) -> None:
        self.limiter.stop()
        if self.stream is not None:
            self.stream.stop()

    def on_joint_state(
        self, names: Sequence[str], positions: Sequence[float], velocities: Sequence[float], now_s: float
    ) -> str | None:
        """Accept a JointState's fields, or return why not."""
        index = self._joint_order.index(names)
        if index is None:
            return self._reject(
                'joint_names', f'joint state must name every joint of {list(spec.JOINT_NAMES)}, got {list(names)[:12]}'
            )
        if len(positions) != len(names) or len(velocities) != len(names):
            return self._reject(
                'joint_length',
                f'joint state has {len(names)} names, {len(positions)} positions and {len(velocities)} velocities',
            )
        q = np.asarray(positions, dtype=float)[index]
        qd = np.asarray(velocities, dtype=float)[index]
        if not (np.isfinite(q).all() and np.isfinite(qd).all()):
            return self._reject('joint_not_finite', 'joint state has NaN or inf')
        if (q < self._urdf_lower).any() or (q > self._urdf_upper).any():
            return self._reject(
                'joint_out_of_limits', f'joint positions {np.round(q, 3).tolist()} outside the URDF limits'
            )
        if (np.abs(qd) > self._max_joint_speed).any():
            return self._reject('joint_speed', f'joint velocities {np.round(qd, 2).tolist()} beyond twice the limits')
        self._q, self._qd, self._joint_received_s = q, qd, now_s
        return None

    def on_ball(
        self,
        frame_id: str,
        stamp_s: float,
        position_m: Sequence[float],
        velocity_m_s: Sequence[float],
        now_s: float,
        velocity_covariance: Sequence[float] = (0.0,) * 9,
    ) -> str | None:
        """Accept a BallState's fields, or return why not."""
        if frame_id.lstrip('/') != FRAME_WORLD:
            return self._reject('ball_frame', f'ball state in frame {frame_id!r}, expected {FRAME_WORLD!r}')
        p = np.asarray(position_m, dtype=float)
        v = np.asarray(velocity_m_s, dtype=float)
        if p.shape != (3,) or v.shape != (3,) or not (np.isfinite(p).all() and np.isfinite(v).all()):
            return self._reject('ball_not_finite', 'ball state has NaN or inf')
        extent_x_m, extent_y_m = robot_cell.CELL_HALF_EXTENT_M
        if abs(p[0]) > extent_x_m or abs(p[1]) > extent_y_m or not 0.0 <= p[2] <= 5.0:
            return self._reject('ball_outside_cell', f'ball position {np.round(p, 2).tolist()} m is outside the cell')
        if float(np.linalg.norm(v)) > self.config.max_ball_speed_m_s:
            return self._reject('ball_speed', f'ball speed {float(np.linalg.norm(v)):.1f} m/s is implausible')
        variances = np.asarray(velocity_covariance, dtype=float).reshape(-1)
        if variances.shape != (9,) or not np.isfinite(variances).all():
            return self._reject('ball_not_finite', 'ball velocity covariance is not 9 finite numbers')
        velocity_std = float(np.sqrt(max(variances[[0, 4, 8]].max(), 0.0)))
        if velocity_std > self.config.max_ball_velocity_std_m_s:
            # An estimate that has not settled yet (a new ball, a bounce): the actor would swing at a guess.
            return self._reject(
                'ball_uncertain',
                f'ball velocity uncertain ({velocity_std:.2f} m/s std, accepted '
                f'up to {self.config.max_ball_velocity_std_m_s} m/s)',
            )
        age_s = now_s - stamp_s
        if stamp_s <= 0.0 or not -self.period_s <= age_s <= self.config.max_ball_age_s:
            return self._reject(
                'ball_stamp',
                f'ball stamp {stamp_s:.3f} s is {age_s:.3f} s old at {now_s:.3f} s '
                f'(accepted: 0 to {self.config.max_ball_age_s} s)',
            )
        if self._ball is not None and stamp_s <= self._ball.stamp_s:
            return self._reject('ball_stamp_order', f'ball stamp {stamp_s:.4f} s not after the last one')
        self._ball = _Ball(p, v, stamp_s, now_s)
        return None

    def on_goal(self, frame_id: str, x_m: float, y_m: float) -> str | None:
        if frame_id.lstrip('/') != FRAME_WORLD:
            return self._reject('goal_frame', f'goal in frame {frame_id!r}, expected {FRAME_WORLD!r}')
        try:
            check_goal((x_m, y_m))
        except ValueError as error:
            return self._reject('goal_value', str(error))
        self.goal_xy_m = np.array([x_m, y_m], dtype=np.float32)
        return None

    # --- scheduling --------------------------------------------------------------------------------
    def ball_fresh(self, now_s: float) -> bool:
        return self._ball is not None and now_s - self._ball.received_s <= self.config.ball_timeout_s

    def joints_fresh(self, now_s: float) -> bool:
        return now_s - self._joint_received_s <= self.config.joint_timeout_periods * self.period_s

    def ball_step_due(self, now_s: float) -> bool:
        """After an accepted ball message: does it drive a policy step now (phase-locked)?"""
        if self.state == State.DISABLED or self._ball is None:
            return False
        if self.state == State.READY:
            return True  # a ball has come: start playing at once
        if now_s - self._last_step_s < MIN_STEP_SPACING_PERIODS * self.period_s:
            return False
        return now_s >= self._grid_s - STEP_TOLERANCE_PERIODS * self.period_s

    def _advance_step_grid(self, now_s: float) -> None:
        """After a policy step: the next grid point, a period on; after a gap (the first step, joint states
        that stopped) the grid starts again a period after this step."""
        if abs(now_s - self._grid_s) > self.period_s:
            self._grid_s = now_s
        self._grid_s += self.period_s

    def fallback_step_due(self, now_s: float) -> bool:
        """While playing: no ball message qualified in time, step on the latest ball."""
        return self.state == State.PLAYING and now_s >= self._grid_s + STEP_TOLERANCE_PERIODS * self.period_s

    def timer_step_due(self, now_s: float) -> bool:
        """The 60 Hz timer drives ready moves (and notices a ball gone stale while playing)."""
        if self.state == State.READY:
            return True
        return self.state == State.PLAYING and (not self.ball_fresh(now_s) or self.fallback_step_due(now_s))

    # --- the step ----------------------------------------------------------------------------------
    def step(self, now_s: float, wall_s: float | None = None) -> StepResult:
        """One period: the command to publish now (None: publish nothing, `problem` says why)."""
        wall_s = time.monotonic() if wall_s is None else wall_s
        if self.state == State.DISABLED:
            return StepResult(None, self.state)
        if not self.joints_fresh(now_s):
            # The limiter keeps its segment: joint states back within the timeout continue it, so two
            # commands that close together never jump; only a longer silence restarts from the measured joints.
            return StepResult(
                None, self.state, problem='joint states stale: no command (the controller holds its last target)'
            )
        if not self.limiter.active or now_s - self._last_command_s > self.config.joint_timeout_periods * self.period_s:
            self.limiter.start(self._q)
            if self.stream is not None:
                self.stream.start(self.limiter.position_rad)
        if self.state == State.PLAYING and not self.ball_fresh(now_s):
            self.state = State.READY
        elif self.state == State.READY and self.ball_fresh(now_s):
            self.state = State.PLAYING
            self.last_action = np.zeros(spec.NUM_ACTIONS, dtype=np.float32)  # as at a training episode start
            self._grid_s = -math.inf
        policy = self.state == State.PLAYING
        if policy:
            command = self._policy_command(now_s)
            self._advance_step_grid(now_s)
            self._last_step_s = now_s
        else:
            command = self.limiter.step(_HOME, self.config.home_speed_rad_s, self.config.home_acceleration_rad_s2)
        self._record_command(now_s, wall_s, policy)
        if self.stream is not None:
            command = self.stream.aim(command, now_s)
            self._stream_at_end = False
        return StepResult(command, self.state, policy=policy)

    def stream_command(self, now_s: float) -> np.ndarray | None:
        """Between steps (call it at the controller's rate, e.g. on every joint state): the stream's point to
        publish now, or None (not streaming, disabled, joint states stale, or the segment's end already sent)."""
        if (
            self.stream is None
            or not self.stream.active
            or self.state == State.DISABLED
            or not self.joints_fresh(now_s)
            or self._stream_at_end
        ):
            return None
        self._stream_at_end = self.stream.arrived(now_s)
        return self.stream.point(now_s)

    def _policy_command(self, now_s: float) -> np.ndarray:
        ball = self._ball
        position_m, velocity_m_s = ball.position_m, ball.velocity_m_s
        if self.config.predict_ball:
            # The ball as it is now, not as the tracker saw it (ball_prediction says why).
            position_m, velocity_m_s = predict_ball(position_m, velocity_m_s, now_s - ball.stamp_s)
        obs = build_observation(self._q, self._qd, position_m, velocity_m_s, self.goal_xy_m, self.last_action)
        started = self._perf_counter()
        raw = np.asarray(self.actor(obs), dtype=np.float32).reshape(-1)
        self.inference.add(self._perf_counter() - started)
        if raw.shape != (spec.NUM_ACTIONS,) or not np.isfinite(raw).all():
            # Never reaches the arm: hold the course (the limiter brakes toward where it is going).
            self.counts['actor_output_rejected'] += 1
            return self.limiter.step(self.limiter.position_rad)
        self.last_action = spec.clip_action(raw)
        return self.limiter.step(spec.decode_action(raw).astype(np.float64))

    def _record_command(self, now_s: float, wall_s: float, policy: bool) -> None:
        if self._last_state_for_period == self.state and now_s - self._last_command_s < 3.0 * self.period_s:
            if policy:
                self.period.add(now_s - self._last_command_s)
                self.period_wall.add(wall_s - self._last_command_wall_s)
            else:
                self.period_ready.add(now_s - self._last_command_s)
        self._last_state_for_period = self.state
        self._last_command_s, self._last_command_wall_s = now_s, wall_s
        self.counts['commands'] += 1
        self.counts['policy_steps' if policy else 'home_steps'] += 1

    def record_published(
        self, published_s: float, ball_driven: bool, wall_received_s: float | None, wall_published_s: float
    ) -> None:
        """After a policy step's command was published (`published_s` on the node clock): for a ball-driven
        step the latency from the ball's stamp and from the message's callback (wall clock); for a fallback
        step the age of the ball it used."""
        if self._ball is None:
            return
        if ball_driven:
            self.latency.add(published_s - self._ball.stamp_s)
            if wall_received_s is not None:
                self.receipt_latency.add(wall_published_s - wall_received_s)
        else:
            self.fallback_ball_age.add(published_s - self._ball.stamp_s)
        self.counts['ball_driven_steps' if ball_driven else 'fallback_steps'] += 1

    def at_home(self) -> bool:
        if self._q is None or not self.limiter.active:
            return False
        return bool(
            np.abs(self._q - _HOME).max() <= self.config.home_tolerance_rad
            and np.abs(self.limiter.position_rad - _HOME).max() <= 1e-6
        )

    def status(self, now_s: float) -> dict:
        period = self.period.summary()
        if self.period.values:
            jitter = np.abs(np.fromiter(self.period.values, dtype=float) - self.period_s) * 1e3
            period['jitter_p99'] = round(float(np.percentile(jitter, 99)), 4)
            period['jitter_max'] = round(float(jitter.max()), 4)
        return {
            'state': self.state.value,
            'at_home': self.at_home(),
            'ball_fresh': self.ball_fresh(now_s),
            'joints_fresh': self.joints_fresh(now_s),
            'goal_xy_m': [round(float(v), 4) for v in self.goal_xy_m],
            'period_ms': period,
            'period_wall_ms': self.period_wall.summary(),
            'period_ready_ms': self.period_ready.summary(),
            'latency_ms': self.latency.summary(),
            'receipt_latency_ms': self.receipt_latency.summary(),
            'fallback_ball_age_ms': self.fallback_ball_age.summary(),
            'inference_ms': self.inference.summary(),
            'counts': dict(self.counts),
            'rejected': dict(self.rejected),
        }
