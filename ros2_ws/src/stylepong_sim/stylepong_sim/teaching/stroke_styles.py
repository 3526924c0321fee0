"""Hand-made stroke styles for the virtual teacher: key poses read from a YAML file, checked before a drag.

A style file (config/styles/<name>.yaml) gives the key poses of the strokes it teaches, in the shape of
teacher.StrokeShape, one mapping per swing:

    forward:
      back_offset_m: [-0.10, -0.06, -0.07]     # paddle centre from home, world axes (x forward, y left, z up)
      hit_offset_m: [0.06, 0.0, 0.05]
      follow_offset_m: [0.16, -0.02, 0.13]
      yaw_rad: [-0.20, 0.0, 0.15]              # blade turned about the vertical: back-swing, hit, follow-through
      pitch_rad: [0.6, 0.6, 0.6]               # optional: blade opened (face up) at each; default the
                                               # teacher's blade_pitch_rad, held from the back-swing on
    leftward: ...

A person's takes vary about these poses as about the shipped ones (teacher.sample_variation). Before the
arm is dragged, `check_stroke` follows the take's full paddle pose (position, yaw and pitch) with the
arm's inverse kinematics from home, as the dragged arm moves, and refuses a stroke that leaves the joint
limits, passes near the UR5's shoulder singularity (the wrist close to the plane of the shoulder's two
axes, where a dragged arm flips its shoulder), flips a joint, straightens the elbow, dips the blade into
the table, or whose label could be mistaken (a leftward hit must lie to the robot's left and face left,
and so on). The checks are the shipped strokes' (test_teacher_variation.py), with a shoulder margin that
allows an opened blade.
"""

from __future__ import annotations

import math
import pathlib
from dataclasses import dataclass

import numpy as np
import pinocchio as pin
import yaml

from stylepong_description import robot_model
from stylepong_sim import world_spec
from stylepong_sim.teaching.teacher import SWINGS, CellKinematics, StrokePath, StrokeShape

STYLES_DIR = pathlib.Path(__file__).resolve().parents[2] / 'config' / 'styles'
KEYS = ('back_offset_m', 'hit_offset_m', 'follow_offset_m', 'yaw_rad', 'pitch_rad')
REQUIRED_KEYS = KEYS[:4]

# The margins a style's takes keep. The wrist's distance from the shoulder plane: the upright shipped
# strokes keep 0.22 m; their opened blade comes within 0.02 m, where the shoulder pan whips round at the
# UR5's speed limit. 0.06 m keeps a slow drag's shoulder pan under about 1.5 rad/s.
MIN_SHOULDER_CLEARANCE_M = 0.06
MIN_ELBOW_BEND_RAD = 0.5  # short of a straight arm (the elbow singularity)
MAX_JOINT_STEP_RAD = 0.15  # per 20 ms of the path: more is a flip of the shoulder or wrist
JOINT_LIMIT_MARGIN_RAD = 0.05
SIDE_HIT_MIN_Y_M = 0.09  # a leftward (rightward) hit at least this far left (right) of home
SIDE_HIT_MIN_YAW_RAD = 0.2  # ... with the blade turned at least this far towards its side
SIDE_SWEEP_MIN_M = 0.08  # ... sweeping at least this far towards its side, back-swing to follow-through
FORWARD_HIT_MAX_Y_M = 0.03  # a forward hit this close to straight ahead
FORWARD_HIT_MAX_YAW_RAD = 0.1
FORWARD_SWEEP_MAX_M = 0.1
MAX_OFFSET_M = 0.6  # no key pose further than this from home (beyond the arm's reach round it)
MAX_ANGLE_RAD = 1.2  # yaw and pitch at a key pose


def _vector(value, name: str, size: int, where: str) -> tuple[float, ...]:
    if not (
        isinstance(value, list)
        and len(value) == size
        and all(isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) for v in value)
    ):
        raise ValueError(f'{where}: {name} must be a list of {size} finite numbers, got {value!r}')
    return tuple(float(v) for v in value)


def shape_from_mapping(entry, where: str) -> StrokeShape:
    """One swing's key poses from its YAML mapping; ValueError names the swing and the key."""
    if not isinstance(entry, dict):
        raise ValueError(f'{where}: expected a mapping of {", ".join(KEYS)}, got {entry!r}')
    unknown = sorted(set(entry) - set(KEYS))
    missing = [k for k in REQUIRED_KEYS if k not in entry]
    faults = ([f'unknown key(s) {", ".join(map(str, unknown))}'] if unknown else []) + (
        [f'missing {", ".join(missing)}'] if missing else []
    )
    if faults:
        raise ValueError(f'{where}: ' + '; '.join(faults))
    offsets = [_vector(entry[k], k, 3, where) for k in KEYS[:3]]
    for name, offset in zip(KEYS[:3], offsets):
        if np.linalg.norm(offset) > MAX_OFFSET_M:
            raise ValueError(f'{where}: {name} is {np.linalg.norm(offset):.2f} m from home, more than {MAX_OFFSET_M} m')
    yaws = _vector(entry['yaw_rad'], 'yaw_rad', 3, where)
    pitches = None if entry.get('pitch_rad') is None else _vector(entry['pitch_rad'], 'pitch_rad', 3, where)
    for name, angles in (('yaw_rad', yaws), ('pitch_rad', pitches or ())):
        if any(abs(a) > MAX_ANGLE_RAD for a in angles):
            raise ValueError(f'{where}: {name} must stay within +-{MAX_ANGLE_RAD} rad, got {list(angles)}')
    if pitches is not None and min(pitches) < 0.0:
        raise ValueError(f'{where}: pitch_rad opens the blade (>= 0), got {list(pitches)}')
    return StrokeShape(*offsets, *yaws, pitch_rad=pitches)


def load_strokes_file(path: str | pathlib.Path) -> dict[str, StrokeShape]:
    """The swings a style file teaches; ValueError in one line naming the file (and the swing, the key)."""
    path = pathlib.Path(path)
    try:
        document = yaml.safe_load(path.read_text())
    except OSError as error:
        raise ValueError(f'strokes file {path}: cannot read it ({error.strerror})') from error
    except yaml.YAMLError as error:
        raise ValueError(f'strokes file {path}: not YAML ({str(error).splitlines()[0]})') from error
    if not isinstance(document, dict) or not document:
        raise ValueError(f'strokes file {path}: expected a mapping of swings ({", ".join(SWINGS)}) to key poses')
    unknown = sorted(str(k) for k in document if k not in SWINGS)
    if unknown:
        raise ValueError(f'strokes file {path}: unknown swing(s) {", ".join(unknown)} (known: {", ".join(SWINGS)})')
    return {swing: shape_from_mapping(entry, f'strokes file {path}, {swing}') for swing, entry in document.items()}


def resolve_strokes_file(name_or_path: str) -> pathlib.Path:
    """A path as given, or a style's name (`long`) as config/styles/<name>.yaml."""
    path = pathlib.Path(name_or_path)
    if path.suffix in ('.yaml', '.yml') or path.parent != pathlib.Path('.'):
        return path
    return STYLES_DIR / f'{name_or_path}.yaml'


@dataclass(frozen=True)
class StrokeCheck:
    """How one take's joint path fares (what `check_stroke` judges)."""

    min_shoulder_clearance_m: float
    min_elbow_bend_rad: float
    min_joint_limit_margin_rad: float
    max_joint_step_rad: float
    peak_joint_speed_rad_s: float  # of the path itself; the dragged arm lags and smooths it a little
    peak_joint: str


class StrokeKinematics:
    """The arm's joint path for a stroke's via-points (the paddle centre's full pose), followed from home."""

    def __init__(self):
        self.kin = CellKinematics()
        self.centre = self.kin.frame_id(robot_model.PADDLE_CENTRE_FRAME)
        self.wrist = self.kin.frame_id('wrist_3_joint')  # where the axes of wrists 2 and 3 meet
        self.home_q = np.array(world_spec.HOME_JOINT_POSITIONS_RAD)
        self.home_rotation = self.kin.pose(self.home_q, self.centre).rotation.copy()
        # The Jacobian's linear and angular rows from the base's axes to the world's.
        rotation = self.kin.base.rotation
        self._to_world = np.block([[rotation, np.zeros((3, 3))], [np.zeros((3, 3)), rotation]])

    def joint_path_rad(self, path: StrokePath, dt_s: float = 0.02) -> np.ndarray:
        """Joint positions putting the paddle centre on each via-point (damped least squares from the last)."""
        model, data = self.kin.model, self.kin.data
        q = self.home_q.copy()
        trajectory = []
        for t in np.arange(0.0, path.duration_s + 1e-9, dt_s):
            via = path.at(t)
            target = pin.SE3(via.rotation(self.home_rotation), via.position_m)
            for _ in range(50):
                current = self.kin.pose(q, self.centre)
                error = np.concatenate(
                    [target.translation - current.translation, pin.log3(target.rotation @ current.rotation.T)]
                )
                if np.linalg.norm(error) < 1e-8:
                    break
                pin.computeJointJacobians(model, data, q)
                jacobian = self._to_world @ pin.getFrameJacobian(model, data, self.centre, pin.LOCAL_WORLD_ALIGNED)
                q = q + jacobian.T @ np.linalg.solve(jacobian @ jacobian.T + 1e-8 * np.eye(6), error)
            if np.linalg.norm(error) > 1e-6:
                raise ValueError(f'the arm cannot reach the via-point {t:.2f} s into the clip')
            trajectory.append(q.copy())
        return np.array(trajectory)

    def shoulder_clearance_m(self, q: np.ndarray) -> float:
        """Distance of the wrist from the plane of the shoulder's two axes (zero: the shoulder singularity)."""
        pin.framesForwardKinematics(self.kin.model, self.kin.data, q)
        shoulder = self.kin.data.oMi[2]  # shoulder_lift_joint, rotating about its y axis
        normal = np.cross([0.0, 0.0, 1.0], shoulder.rotation[:, 1])
        normal /= np.linalg.norm(normal)
        return float(abs((self.kin.data.oMf[self.wrist].translation - shoulder.translation) @ normal))

    def measure(self, path: StrokePath, dt_s: float = 0.02) -> StrokeCheck:
        q = self.joint_path_rad(path, dt_s)
        limits = robot_model.joint_limits()
        speed = np.abs(np.diff(q, axis=0)) / dt_s
        return StrokeCheck(
            min_shoulder_clearance_m=min(self.shoulder_clearance_m(a) for a in q),
            min_elbow_bend_rad=float(np.min(np.abs(q[:, 2]))),
            min_joint_limit_margin_rad=float(min(np.min(q - limits.lower_rad), np.min(limits.upper_rad - q))),
            max_joint_step_rad=float(np.max(np.abs(np.diff(q, axis=0)))),
            peak_joint_speed_rad_s=float(speed.max()),
            peak_joint=robot_model.JOINT_NAMES[int(speed.max(axis=0).argmax())],
        )


def label_problem(swing: str, path: StrokePath) -> str | None:
    """Why the take could be mistaken for another label or breaks a stroke's order; None if it cannot."""
    home = path.ready
    hit_y_m, sweep_y_m = path.hit[1] - home[1], path.follow[1] - path.back[1]
    hit_yaw_rad = path.yaws[2]
    side = {'leftward': 1.0, 'rightward': -1.0}.get(swing)
    if side is None:
        if (
            abs(hit_y_m) > FORWARD_HIT_MAX_Y_M
            or abs(hit_yaw_rad) > FORWARD_HIT_MAX_YAW_RAD
            or abs(sweep_y_m) > FORWARD_SWEEP_MAX_M
        ):
            return (
                f'a forward stroke meets the ball straight ahead (hit {hit_y_m:+.3f} m, yaw {hit_yaw_rad:+.2f} rad '
                f'from home; sweep {sweep_y_m:+.3f} m sideways)'
            )
    elif (
        side * hit_y_m < SIDE_HIT_MIN_Y_M
        or side * hit_yaw_rad < SIDE_HIT_MIN_YAW_RAD
        or side * sweep_y_m < SIDE_SWEEP_MIN_M
    ):
        return (
            f'a {swing} stroke meets the ball >= {SIDE_HIT_MIN_Y_M} m to its side facing it, sweeping that way '
            f'(hit {hit_y_m:+.3f} m, yaw {hit_yaw_rad:+.2f} rad; sweep {sweep_y_m:+.3f} m; +y is the left)'
        )
    if not path.back[0] < home[0] < path.hit[0] < path.follow[0]:
        return 'the stroke goes back-swing (behind home) -> hit (in front) -> follow-through (further in front)'
    return None


def check_stroke(swing: str, path: StrokePath, kinematics: StrokeKinematics | None = None) -> StrokeCheck:
    """The take's measures; ValueError in one line when it would not make a clean, unmistakable stroke."""
    problem = label_problem(swing, path)
    if problem:
        raise ValueError(problem)
    positions = np.array([path.at(t).position_m for t in np.arange(0.0, path.duration_s, 0.01)])
    over_table = positions[:, 0] > -world_spec.HALF_LENGTH_M - robot_model.PADDLE.blade_radius_m
    if np.any(positions[over_table, 2] <= world_spec.TABLE_HEIGHT_M + robot_model.PADDLE.blade_radius_m):
        raise ValueError('the blade would dip into the table')
    check = (kinematics or StrokeKinematics()).measure(path)
    if check.min_joint_limit_margin_rad < JOINT_LIMIT_MARGIN_RAD:
        raise ValueError(f'a joint comes within {check.min_joint_limit_margin_rad:.3f} rad of its limit')
    if check.max_joint_step_rad > MAX_JOINT_STEP_RAD:
        raise ValueError(f'a joint flips ({check.max_joint_step_rad:.2f} rad in 20 ms)')
    if check.min_shoulder_clearance_m < MIN_SHOULDER_CLEARANCE_M:
        raise ValueError(
            f'the wrist passes {check.min_shoulder_clearance_m:.3f} m from the shoulder singularity '
            f'(at least {MIN_SHOULDER_CLEARANCE_M} m)'
        )
    if check.min_elbow_bend_rad < MIN_ELBOW_BEND_RAD:
        raise ValueError(f'the elbow straightens to {check.min_elbow_bend_rad:.2f} rad (at least {MIN_ELBOW_BEND_RAD})')
    return check
