"""Strokes of an evaluation: each ball's joint motion, the direction the ball came from, and their file.

A stroke is what the arm did for one incoming ball: its joint positions at the policy rate (60 Hz),
frame 0 at the ball's launch and frame i after policy step i, up to FOLLOW_THROUGH_S after the step in
which the paddle first touched the ball (or up to the referee's verdict when it never did, or when
the verdict comes first: after it the environment has already reset the arm).

Directions. The demonstrations are labelled forward, leftward and rightward by where the stroke meets
the ball (stylepong_sim.teaching.teacher.STROKES: hits straight ahead of the paddle's home pose, 0.16 m to the
robot's left, 0.18 m to its right; world +y is the robot's left). A ball is labelled the same way, by
where it reaches the robot: its lateral position when it crosses the paddle's home plane (the plane
x = x of the paddle centre at the home pose) after its bounce on the robot's half. Its offset from the
paddle's home y decides, with the thresholds halfway between the demonstrations' hitting points:

    offset >  LEFTWARD_ABOVE_M  (+0.08 m)   leftward
    offset <  RIGHTWARD_BELOW_M (-0.09 m)   rightward
    otherwise                               forward

so a ball is given the stroke whose demonstrated hitting point is nearest to where it arrives.
Where the paddle meets the ball before that plane, the crossing is extrapolated along the ball's
horizontal heading from its last sample before the contact: in this world (gravity and quadratic drag
along the velocity, no spin) the heading over the table never turns, and a table bounce scales both
horizontal components alike, so that straight line is where the untouched ball would have crossed.

The stroke file (`save_strokes`, `load_strokes`; .npz, S strokes, N frames in all; stroke s is frames
stroke_start[s] .. stroke_start[s] + stroke_length[s] - 1):
  q_rad              (N, 6) float32  joint positions, columns in joint_names order (URDF), 60 Hz
  ball_position_m    (N, 3) float32  true ball position at the same frames
  stroke_start, stroke_length, seed, ball, hit_frame, verdict_frame   (S,) int64
                     ball: the environment index in its seed's world (its first ball); hit_frame: the
                     frame after the first paddle contact (-1: none); verdict_frame: the frame of the
                     verdict (the stroke may end before it)
  direction, outcome (S,) str        outcome: the referee's verdict ('returned' is a success)
  success, hit       (S,) bool
  arrival_y_m        (S,) float64    world y where the ball crosses the paddle's home plane
  launch_velocity_m_s (S, 3) float64, launch_speed_m_s (S,) float64   the ball's at its launch
  rate_hz, follow_through_s, plane_x_m, paddle_home_y_m, leftward_above_m, rightward_below_m  () float64
  joint_names (6,) str; actor, speed () str
"""

from __future__ import annotations

import functools
import os
import pathlib
import tempfile
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from stylepong_description.robot_cell import STROKE_LABELS as DIRECTIONS  # noqa: F401  (the labels, for users)

# Halfway between the demonstrated hitting points (teacher.STROKES hit offsets in y: 0, +0.16, -0.18 m).
LEFTWARD_ABOVE_M = 0.08
RIGHTWARD_BELOW_M = -0.09
FOLLOW_THROUGH_S = 0.3  # the stroke goes on this long after the paddle's first contact
NO_FRAME = -1


@functools.cache
def paddle_home_position_m() -> tuple[float, float, float]:
    """World position of the paddle centre at the home pose (the robot model placed by the world spec)."""
    import pinocchio as pin

    from stylepong_description import robot_model
    from stylepong_sim import world_spec

    model = robot_model.pinocchio_model()
    data = model.createData()
    pin.framesForwardKinematics(model, data, np.asarray(world_spec.HOME_JOINT_POSITIONS_RAD, dtype=float))
    base = pin.SE3(*world_spec.robot_base_pose())
    position = (base * data.oMf[model.getFrameId(robot_model.PADDLE_CENTRE_FRAME)]).translation
    return float(position[0]), float(position[1]), float(position[2])


def direction_of(arrival_y_m: float, paddle_home_y_m: float | None = None) -> str:
    """The stroke direction of a ball that crosses the paddle's home plane at world y = arrival_y_m."""
    home_y = paddle_home_position_m()[1] if paddle_home_y_m is None else paddle_home_y_m
    offset_m = arrival_y_m - home_y
    if offset_m > LEFTWARD_ABOVE_M:
        return 'leftward'
    if offset_m < RIGHTWARD_BELOW_M:
        return 'rightward'
    return 'forward'


def arrival_y_m(
    ball_position_m: np.ndarray, ball_velocity_m_s: np.ndarray, free_frames: int, plane_x_m: float | None = None
) -> float:
    """World y where a ball crosses the plane x = plane_x_m, flying towards the robot (-x).

    ball_position_m, ball_velocity_m_s: [T, 3] samples of the ball from its launch; only the first
    `free_frames` are used (those before anything but the table touched it). A crossing between two
    of them is interpolated linearly; without one, the crossing is extrapolated from the last free
    sample along its horizontal heading (see the module docstring for why that line is exact here).
    """
    plane = paddle_home_position_m()[0] if plane_x_m is None else plane_x_m
    p = np.asarray(ball_position_m, dtype=float)[: max(int(free_frames), 1)]
    v = np.asarray(ball_velocity_m_s, dtype=float)[: len(p)]
    ahead = p[:, 0] > plane
    crossed = np.flatnonzero(ahead[:-1] & ~ahead[1:])
    if len(crossed):
        i = int(crossed[0])
        fraction = (p[i, 0] - plane) / (p[i, 0] - p[i + 1, 0])
        return float(p[i, 1] + fraction * (p[i + 1, 1] - p[i, 1]))
    last_p, last_v = p[-1], v[-1]
    if last_v[0] >= 0.0:
        # Not heading for the robot (cannot happen for a served ball): where it is is the best answer.
        return float(last_p[1])
    return float(last_p[1] + (plane - last_p[0]) * last_v[1] / last_v[0])


def stroke_end_frame(verdict_frame: int, hit_frame: int, rate_hz: float) -> int:
    """Last frame of a stroke: FOLLOW_THROUGH_S after the first contact, never past the verdict."""
    if hit_frame == NO_FRAME:
        return verdict_frame
    return min(verdict_frame, hit_frame + int(round(FOLLOW_THROUGH_S * rate_hz)))


@dataclass
class Stroke:
    """One ball's stroke (frames as in the module docstring)."""

    seed: int
    ball: int
    joint_positions_rad: np.ndarray  # [T, 6]
    ball_position_m: np.ndarray  # [T, 3]
    direction: str
    arrival_y_m: float
    launch_velocity_m_s: np.ndarray  # [3]
    outcome: str
    success: bool
    hit: bool
    hit_frame: int
    verdict_frame: int

    @property
    def launch_speed_m_s(self) -> float:
        return float(np.linalg.norm(self.launch_velocity_m_s))


@dataclass
class StrokeFile:
    """What `load_strokes` returns: the strokes and the file's scalars."""

    strokes: list[Stroke]
    rate_hz: float
    joint_names: tuple[str, ...]
    actor: str
    speed: str
    plane_x_m: float
    paddle_home_y_m: float


def save_strokes(
    path: str | os.PathLike,
    strokes: Sequence[Stroke],
    *,
    rate_hz: float,
    joint_names: Sequence[str],
    actor: str,
    speed: str,
) -> pathlib.Path:
    """Write the strokes (layout in the module docstring) atomically: a half-written file never replaces a good one."""
    path = pathlib.Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    lengths = np.array([len(s.joint_positions_rad) for s in strokes], dtype=np.int64)
    starts = np.concatenate([[0], np.cumsum(lengths)[:-1]]).astype(np.int64) if len(strokes) else lengths
    width = len(joint_names)

    def frames(attribute: str, columns: int) -> np.ndarray:
        parts = [np.asarray(getattr(s, attribute), dtype=np.float32).reshape(-1, columns) for s in strokes]
        return np.concatenate(parts) if parts else np.zeros((0, columns), dtype=np.float32)

    home_x, home_y, _ = paddle_home_position_m()
    arrays = {
        'q_rad': frames('joint_positions_rad', width),
        'ball_position_m': frames('ball_position_m', 3),
        'stroke_start': starts,
        'stroke_length': lengths,
        'seed': np.array([s.seed for s in strokes], dtype=np.int64),
        'ball': np.array([s.ball for s in strokes], dtype=np.int64),
        'hit_frame': np.array([s.hit_frame for s in strokes], dtype=np.int64),
        'verdict_frame': np.array([s.verdict_frame for s in strokes], dtype=np.int64),
        'direction': np.array([s.direction for s in strokes], dtype=str),
        'outcome': np.array([s.outcome for s in strokes], dtype=str),
        'success': np.array([s.success for s in strokes], dtype=bool),
        'hit': np.array([s.hit for s in strokes], dtype=bool),
        'arrival_y_m': np.array([s.arrival_y_m for s in strokes], dtype=np.float64),
        'launch_velocity_m_s': np.array([s.launch_velocity_m_s for s in strokes], dtype=np.float64).reshape(-1, 3),
        'launch_speed_m_s': np.array([s.launch_speed_m_s for s in strokes], dtype=np.float64),
        'rate_hz': np.float64(rate_hz),
        'follow_through_s': np.float64(FOLLOW_THROUGH_S),
        'plane_x_m': np.float64(home_x),
        'paddle_home_y_m': np.float64(home_y),
        'leftward_above_m': np.float64(LEFTWARD_ABOVE_M),
        'rightward_below_m': np.float64(RIGHTWARD_BELOW_M),
        'joint_names': np.array(list(joint_names), dtype=str),
        'actor': np.array(actor),
        'speed': np.array(speed),
    }
    handle, temporary = tempfile.mkstemp(prefix=path.name + '.', suffix='.part', dir=path.parent)
    try:
        with os.fdopen(handle, 'wb') as stream:
            np.savez_compressed(stream, **arrays)
        os.chmod(temporary, 0o644)  # mkstemp makes it private; a result file is for everyone to read
        os.replace(temporary, path)
    except BaseException:
        pathlib.Path(temporary).unlink(missing_ok=True)
        raise
    return path


def load_strokes(path: str | os.PathLike) -> StrokeFile:
    """Read a strokes file (.npz) written by save_strokes."""
    with np.load(path, allow_pickle=False) as stored:
        # Each array once: an NpzFile reads (and decompresses) an array again at every access.
        data = {name: stored[name] for name in stored.files}
        strokes = []
        for s in range(len(data['stroke_start'])):
            frames = slice(int(data['stroke_start'][s]), int(data['stroke_start'][s] + data['stroke_length'][s]))
            strokes.append(
                Stroke(
                    seed=int(data['seed'][s]),
                    ball=int(data['ball'][s]),
                    joint_positions_rad=data['q_rad'][frames],
                    ball_position_m=data['ball_position_m'][frames],
                    direction=str(data['direction'][s]),
                    arrival_y_m=float(data['arrival_y_m'][s]),
                    launch_velocity_m_s=data['launch_velocity_m_s'][s],
                    outcome=str(data['outcome'][s]),
                    success=bool(data['success'][s]),
                    hit=bool(data['hit'][s]),
                    hit_frame=int(data['hit_frame'][s]),
                    verdict_frame=int(data['verdict_frame'][s]),
                )
            )
        return StrokeFile(
            strokes=strokes,
            rate_hz=float(data['rate_hz']),
            joint_names=tuple(str(n) for n in data['joint_names']),
            actor=str(data['actor']),
            speed=str(data['speed']),
            plane_x_m=float(data['plane_x_m']),
            paddle_home_y_m=float(data['paddle_home_y_m']),
        )
