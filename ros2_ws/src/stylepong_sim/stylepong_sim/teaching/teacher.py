"""The virtual teacher: a person's hand dragging the paddle through a table-tennis stroke (no ROS here).

The hand is a spring-damper between the paddle and a via-point that moves along the stroke; what it
pushes with is the wrench `virtual_teacher` publishes on /sim/hand_wrench. The arm only moves because
drag_teach (FDCC) yields to that push, as it would to a person's hand on the real robot.

A stroke is four key poses of the paddle centre, given as offsets from its home pose (world_spec's
HOME_JOINT_POSITIONS_RAD, robot placement ROBOT_BASE_POSITION_M), with the blade turned about the
vertical by a yaw:

    ready -> back-swing -> hit (the fastest point, in front of the robot) -> follow-through

The blade stays upright unless TeacherConfig.blade_pitch_rad opens it (turns its face up) during the
back-swing and holds it open to the end: an upright blade strikes a ball down onto the robot's own half.
TeacherConfig.side_turn_rad swings a leftward or rightward stroke round the shoulder pan's axis towards
its side, to meet a ball wider than the nominal hitting points; TeacherConfig.side_reach_m carries the
whole stroke further to its side, the arm reaching out for the ball.

The back-swing is a minimum-jerk move from rest to rest. The forward swing runs from the back-swing
through the hitting point to the follow-through along the quadratic through those three points, timed
by a minimum-jerk profile (top speed half-way through it) that passes the hitting point near its top
speed (at 85-100 % of it for the nominal strokes, 75 % or more for any take). Forward, leftward and
rightward strokes differ in where the ball is met (straight ahead, to the robot's left, to its right:
world +y is the robot's left) and in where the blade sweeps and faces.

A person never drags the same stroke twice, and a style is learned from a distribution of takes: a
SwingVariation (drawn from a seed by `sample_variation`) moves the key poses by a few cm, turns the blade
by a few degrees, scales the stroke's amplitude and durations and moves the hit before or after the top
speed, all within the ranges below (VARIATION_RANGES), which keep every take inside the joint limits and
unmistakably forward, leftward or rightward, and, with the blade upright, 0.1 m clear of the shoulder
singularity (the wrist from the base's axis). The opened blade brings the wrist back towards the base:
forward and leftward strokes pass within about 2 cm of the axis (docs/DESIGN.md, Known limits).

World frame (world_spec): x from the robot's end towards the opponent, y to the robot's left, z up.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from stylepong_common.settings import check_ranges, non_negative, positive, within
from stylepong_description import robot_model
from stylepong_description.robot_cell import STROKE_LABELS as SWINGS  # a swing per stroke label
from stylepong_sim import world_spec

# Which side each swing goes to (+: the robot's left, world +y): the sign of TeacherConfig.side_turn_rad's
# turn about the vertical and of side_reach_m's carry along y.
SIDE_SIGN = {'forward': 0.0, 'leftward': 1.0, 'rightward': -1.0}
# The turn swings the stroke round a point 0.35 m behind home, so it also takes the hit back from the end
# line: at 1 rad a leftward hit is 0.47 m behind it and hardly further to the side than at 0.8 rad.
MAX_SIDE_TURN_RAD = 1.0
# A reach carries the back-swing, hit and follow-through sideways with the arm stretching out: 0.3 m to the
# right leaves the elbow bent by 0.6 rad at the upright blade's follow-through (1.4 rad in the recorded
# opened-blade takes), clear of the elbow singularity (a straight arm); 0.4 m is out of the arm's reach.
# The left's reach ends sooner (the nominal leftward follow-through is already further out), so each side
# has its own limit.
MAX_SIDE_REACH_M = {'leftward': 0.1, 'rightward': 0.3}


@dataclass(frozen=True)
class StrokeShape:
    """Key poses of the paddle centre: offsets (m, world axes) from home and blade yaw (rad) about world z.

    pitch_rad, when given, is how far the blade is opened at the back-swing, hit and follow-through (a
    wrist that turns the face up through the stroke); None holds TeacherConfig.blade_pitch_rad from the
    end of the back-swing on, as the shipped strokes do.
    """

    back_offset_m: tuple[float, float, float]
    hit_offset_m: tuple[float, float, float]
    follow_offset_m: tuple[float, float, float]
    back_yaw_rad: float
    hit_yaw_rad: float
    follow_yaw_rad: float
    pitch_rad: tuple[float, float, float] | None = None


# Home puts the blade centre 0.10 m behind the end line and 0.13 m above the table's height, facing +x.
# Back-swings stay behind the end line, and only 0.10 m behind home: further back the wrist passes over
# the base's axis (the UR5's shoulder singularity), where a dragged arm flips its shoulder. Hits are
# just above the end line, 0.18 m above the table (where a ball that bounced on the robot's half is met);
# follow-throughs rise forwards over the table, short of the arm's reach (elbow bent by more than 1 rad).
STROKES = {
    'forward': StrokeShape(
        back_offset_m=(-0.10, -0.06, -0.07),
        hit_offset_m=(0.06, 0.0, 0.05),
        follow_offset_m=(0.16, -0.02, 0.13),
        back_yaw_rad=-0.20,
        hit_yaw_rad=0.0,
        follow_yaw_rad=0.15,
    ),
    'leftward': StrokeShape(
        back_offset_m=(-0.10, -0.06, -0.05),
        hit_offset_m=(0.03, 0.16, 0.05),
        follow_offset_m=(0.06, 0.28, 0.11),
        back_yaw_rad=-0.10,
        hit_yaw_rad=0.30,
        follow_yaw_rad=0.45,
    ),
    'rightward': StrokeShape(
        back_offset_m=(-0.10, 0.08, -0.05),
        hit_offset_m=(0.05, -0.18, 0.05),
        follow_offset_m=(0.12, -0.30, 0.12),
        back_yaw_rad=0.10,
        hit_yaw_rad=-0.30,
        follow_yaw_rad=-0.45,
    ),
}


# ---------------------------------------------------------------------------------------------------
# Take-to-take variation of a person's stroke
# ---------------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class VariationRanges:
    """The most one take departs from the nominal stroke (STROKES, TeacherConfig's durations), and why.

    test_teacher_variation.py checks the extremes of these ranges: joint limits, the shoulder's clearance,
    the elbow's bend, the blade over the table and each label's direction.
    """

    # Reach of the forward swing (hit and follow-through offsets from home scaled together): a person's
    # strokes differ by about a tenth in size. Only smaller than nominal: the nominal follow-throughs are
    # already near the arm's reach (leftward's elbow is bent by only 1.14 rad there, and the key-pose
    # jitter below brings it to 1.02 rad, just above the 1 rad the strokes keep). Down to 0.85 a
    # leftward or rightward hit stays more than 0.09 m to its side of the forward one, with the jitter.
    amplitude_scale: tuple[float, float] = (0.85, 1.0)
    # Each key pose moved by up to this much per world axis (x, y, z), independently. x is kept small so
    # that back < home < hit < follow-through along x holds for every take (leftward's hit and follow-
    # through are only 0.03 m apart); z so that follow-through > hit > back-swing in height holds and the
    # blade stays well above the table; y is the freest, a person's aim wanders most sideways.
    key_pose_jitter_m: tuple[float, float, float] = (0.01, 0.02, 0.015)
    # The back-swing's depth along x is only made shallower (0 to 3 cm), never deeper: it is already at
    # the 0.10 m behind home beyond which the wrist passes over the base's axis (see STROKES).
    back_shallower_m: tuple[float, float] = (0.0, 0.03)
    # Blade yaw at each key pose, +-3 degrees: the leftward and rightward hits face 0.30 rad to their side,
    # so their sign never changes.
    yaw_jitter_rad: float = 0.05
    # Durations of the back-swing and of the forward swing, +-20 % each (a slow drag varies in tempo).
    # The nominal 2.4 s stroke stays within 1.92-2.88 s (within TeacherConfig.validate's STROKE_S_RANGE) and the
    # fastest forward swing (rightward, x0.8) peaks at 0.8 m/s, under the 1 m/s of a slow drag.
    duration_scale: tuple[float, float] = (0.8, 1.2)
    # Where on the forward swing's path the hit falls (0.5: half-way in time, where the path parameter
    # moves fastest): 0.45-0.55, the ball met slightly before or after that. The moved key poses change
    # which half of the quadratic is longer (and swept faster), so a take meets the ball at 75 % of its
    # top speed or more (85 % or more for the nominal strokes; 200 seeds per swing give 77 % at worst).
    hit_fraction: tuple[float, float] = (0.45, 0.55)


VARIATION_RANGES = VariationRanges()


def _within(value: float, bounds: tuple[float, float], name: str) -> None:
    low, high = bounds
    if not low - 1e-12 <= value <= high + 1e-12:
        raise ValueError(f'{name} must be within {low}-{high}, got {value!r}')


@dataclass(frozen=True)
class SwingVariation:
    """How one take departs from the nominal stroke; the default is no departure (the nominal stroke)."""

    amplitude_scale: float = 1.0  # hit and follow-through offsets scaled
    back_delta_m: tuple[float, float, float] = (0.0, 0.0, 0.0)  # added to the back-swing's offset
    hit_delta_m: tuple[float, float, float] = (0.0, 0.0, 0.0)
    follow_delta_m: tuple[float, float, float] = (0.0, 0.0, 0.0)
    yaw_delta_rad: tuple[float, float, float] = (0.0, 0.0, 0.0)  # back-swing, hit, follow-through
    backswing_scale: float = 1.0
    forward_swing_scale: float = 1.0
    hit_fraction: float = 0.5

    def validate(self, ranges: VariationRanges = VARIATION_RANGES) -> None:
        """Refuse a take outside the stated ranges (one built by hand as well as a drawn one)."""
        _within(self.amplitude_scale, ranges.amplitude_scale, 'amplitude_scale')
        _within(self.backswing_scale, ranges.duration_scale, 'backswing_scale')
        _within(self.forward_swing_scale, ranges.duration_scale, 'forward_swing_scale')
        _within(self.hit_fraction, ranges.hit_fraction, 'hit_fraction')
        for name in ('back_delta_m', 'hit_delta_m', 'follow_delta_m'):
            delta = getattr(self, name)
            for axis, (value, jitter) in enumerate(zip(delta, ranges.key_pose_jitter_m)):
                bounds = ranges.back_shallower_m if (name == 'back_delta_m' and axis == 0) else (-jitter, jitter)
                _within(value, bounds, f'{name}[{axis}]')
        for value in self.yaw_delta_rad:
            _within(value, (-ranges.yaw_jitter_rad, ranges.yaw_jitter_rad), 'yaw_delta_rad')


def sample_variation(
    swing: str, seed: int, strength: float = 1.0, ranges: VariationRanges = VARIATION_RANGES
) -> SwingVariation:
    """One take of `swing` drawn from `seed` (the same seed and swing: the same take).

    `strength` in [0, 1] shrinks every departure from the nominal stroke towards it (0: the nominal
    stroke), so that any strength stays within `ranges`.
    """
    if swing not in STROKES:
        raise ValueError(f'swing must be one of {SWINGS}, got {swing!r}')
    if not (isinstance(seed, int) and seed >= 0):
        raise ValueError(f'seed must be a non-negative integer, got {seed!r}')
    if not 0.0 <= strength <= 1.0:
        raise ValueError(f'strength must be within 0-1, got {strength!r}')
    # One stream per (seed, swing), drawn in a fixed order: a take never depends on other takes.
    rng = np.random.default_rng([seed, SWINGS.index(swing)])
    unit = strength * rng.uniform(-1.0, 1.0, size=16)  # every departure as a fraction of its half-range

    def scaled(u: float, bounds: tuple[float, float]) -> float:
        """1.0 (no change) moved by u in [-1, 1] towards the low (u < 0) or high (u > 0) end of the range."""
        low, high = bounds
        return float(1.0 + u * (high - 1.0)) if u >= 0 else float(1.0 + u * (1.0 - low))

    jitter = np.array(ranges.key_pose_jitter_m)
    back_delta = unit[1:4] * jitter  # its x is mapped onto the shallower-only range below
    shallow_low, shallow_high = ranges.back_shallower_m
    back_delta[0] = shallow_low + 0.5 * (unit[1] + strength) * (shallow_high - shallow_low)
    hit_low, hit_high = ranges.hit_fraction
    return SwingVariation(
        amplitude_scale=scaled(unit[0], ranges.amplitude_scale),
        back_delta_m=tuple(float(v) for v in back_delta),
        hit_delta_m=tuple(float(v) for v in unit[4:7] * jitter),
        follow_delta_m=tuple(float(v) for v in unit[7:10] * jitter),
        yaw_delta_rad=tuple(float(v) for v in unit[10:13] * ranges.yaw_jitter_rad),
        backswing_scale=scaled(unit[13], ranges.duration_scale),
        forward_swing_scale=scaled(unit[14], ranges.duration_scale),
        hit_fraction=float(0.5 * (hit_low + hit_high) + unit[15] * 0.5 * (hit_high - hit_low)),
    )


def varied_shape(shape: StrokeShape, variation: SwingVariation) -> StrokeShape:
    """The key poses of one take. The back-swing is not scaled with the amplitude: its depth is capped."""

    def moved(offset, delta, scale=1.0):
        return tuple(float(scale * o + d) for o, d in zip(offset, delta))

    yaw_back, yaw_hit, yaw_follow = variation.yaw_delta_rad
    return StrokeShape(
        back_offset_m=moved(shape.back_offset_m, variation.back_delta_m),
        hit_offset_m=moved(shape.hit_offset_m, variation.hit_delta_m, variation.amplitude_scale),
        follow_offset_m=moved(shape.follow_offset_m, variation.follow_delta_m, variation.amplitude_scale),
        back_yaw_rad=shape.back_yaw_rad + yaw_back,
        hit_yaw_rad=shape.hit_yaw_rad + yaw_hit,
        follow_yaw_rad=shape.follow_yaw_rad + yaw_follow,
        pitch_rad=shape.pitch_rad,
    )


def minimum_jerk_time(progress: float) -> float:
    """The normalised time tau at which minimum-jerk progress reaches `progress` (bisection: s is monotonic)."""
    low, high = 0.0, 1.0
    for _ in range(60):
        middle = 0.5 * (low + high)
        if minimum_jerk(middle)[0] < progress:
            low = middle
        else:
            high = middle
    return 0.5 * (low + high)


# How long a stroke (back-swing to follow-through) may take: the shipped 2.4 s is a brisk drag; a person
# dragging a UR5 carefully (about 1 rad/s at the fastest joint) takes up to twice that.
STROKE_S_RANGE = (1.5, 6.0)


@dataclass(frozen=True)
class TeacherConfig:
    """Timing of the stroke and the hand's impedance (units in the names). Every setting declares its range
    with its default (stylepong_common.settings); validate checks them and what ties settings together."""

    lead_in_s: float = non_negative(0.3)  # recorded at rest at the ready pose before the back-swing
    backswing_s: float = positive(0.8)
    forward_swing_s: float = positive(1.6)
    end_hold_s: float = non_negative(0.3)  # recorded at rest after the follow-through
    approach_speed_m_s: float = positive(0.25)  # getting to the ready pose (not recorded)
    approach_min_s: float = positive(1.0)
    settle_timeout_s: float = non_negative(4.0)
    settle_position_m: float = non_negative(0.015)
    settle_angle_rad: float = non_negative(0.05)
    settle_speed_m_s: float = non_negative(0.01)
    hand_stiffness_n_per_m: float = non_negative(200.0)
    # Well below the arm's damping: with the loop's delays a gain near 1 rings.
    hand_damping_ns_per_m: float = non_negative(10.0)
    hand_rot_stiffness_nm_per_rad: float = non_negative(15.0)
    hand_rot_damping_nms_per_rad: float = non_negative(1.0)
    # How heavy the person expects the arm to feel (they push ahead of the motion): the arm's damping.
    expected_damping_ns_per_m: float = non_negative(30.0)
    expected_rot_damping_nms_per_rad: float = non_negative(3.0)
    max_force_n: float = positive(35.0)
    max_torque_nm: float = non_negative(3.5)
    # How far the person opens the blade (turns its face up, about its horizontal axis) during the back-swing
    # and holds it open through the hit and the follow-through. 0.6 rad gives the shipped clips, whose
    # strokes return balls; at 0 the blade stays upright as at home and strikes a ball down onto the robot's
    # own half (tools/demo_returns.py, docs/DESIGN.md Known limits). Beyond 1 rad it faces the ceiling more
    # than the opponent.
    blade_pitch_rad: float = within(0.6, 0.0, 1.0)
    # How far a leftward or rightward stroke is turned towards its side about the shoulder pan's axis (the
    # robot base's vertical): a person reaching for a wide ball swings the whole stroke round at the
    # shoulder. The key poses and the blade's yaw turn together, so from the end of the back-swing on the
    # joint path is the unturned one with the shoulder pan moved by this much (every reach, clearance and
    # wrist check of the unturned stroke holds; the back-swing goes straight from home to its turned pose).
    # 0 gives the nominal strokes, whose hits lie within 0.18 m of home; 0.4 rad meets the ball 0.13-0.15 m
    # further out and 0.8 rad 0.19-0.27 m, towards where most balls reach the robot (docs/DESIGN.md Known
    # limits).
    side_turn_rad: float = within(0.0, 0.0, MAX_SIDE_TURN_RAD)
    # How far a leftward or rightward stroke is carried further to its side (world y), the back-swing, hit
    # and follow-through together, with the arm reaching out rather than turning at the shoulder: where the
    # rightward balls reach the robot (up to 0.9 m right of home), a person stretches. 0 gives the nominal
    # strokes; the most for each side is MAX_SIDE_REACH_M (TeacherConfig.validate only bounds it by the
    # larger; check_side_reach the side's).
    side_reach_m: float = within(0.0, 0.0, max(MAX_SIDE_REACH_M.values()))
    # A person waits for an arm that lags (a loaded machine stalls it): the stroke's clock slows down
    # when the paddle is further than this from the via-point, and stops beyond the second distance.
    lag_slowdown_m: float = non_negative(0.03)
    lag_stop_m: float = non_negative(0.08)

    def validate(self) -> None:
        """ValueError naming the first setting out of its range, then a bad pair or a stroke's length."""
        check_ranges(self)
        if self.lag_stop_m <= self.lag_slowdown_m:
            raise ValueError('lag_stop_m must exceed lag_slowdown_m')
        low_s, high_s = STROKE_S_RANGE
        if not low_s <= self.stroke_s <= high_s:
            raise ValueError(
                f'a stroke (back-swing to follow-through) takes {low_s:g}-{high_s:g} s like a slow drag, '
                f'got {self.stroke_s:.2f} s'
            )

    @property
    def stroke_s(self) -> float:
        """Back-swing, forward swing and follow-through."""
        return self.backswing_s + self.forward_swing_s

    @property
    def clip_s(self) -> float:
        """What is recorded: the stroke with the pose held at rest before and after it."""
        return self.lead_in_s + self.stroke_s + self.end_hold_s


# ---------------------------------------------------------------------------------------------------
# Kinematics of the cell
# ---------------------------------------------------------------------------------------------------
def robot_base_in_world() -> pin.SE3:
    """The robot base's pose in the world frame (world_spec.robot_base_pose)."""
    return pin.SE3(*world_spec.robot_base_pose())


class CellKinematics:
    """World poses and velocities of robot frames (the robot model placed as the world spec says)."""

    def __init__(self):
        self.model = robot_model.pinocchio_model()
        self.data = self.model.createData()
        self.base = robot_base_in_world()

    def frame_id(self, name: str) -> int:
        frame_id = self.model.getFrameId(name)
        if frame_id >= self.model.nframes:
            raise ValueError(f'the robot model has no frame {name!r}')
        return frame_id

    def pose(self, q: np.ndarray, frame_id: int) -> pin.SE3:
        pin.framesForwardKinematics(self.model, self.data, np.asarray(q, dtype=float))
        return self.base * self.data.oMf[frame_id]

    def twist(self, q: np.ndarray, qdot: np.ndarray, frame_id: int) -> np.ndarray:
        """(linear, angular) velocity of the frame's origin, world axes."""
        pin.computeJointJacobians(self.model, self.data, np.asarray(q, dtype=float))
        jacobian = pin.getFrameJacobian(self.model, self.data, frame_id, pin.LOCAL_WORLD_ALIGNED)
        velocity = jacobian @ np.asarray(qdot, dtype=float)
        rotation = self.base.rotation
        return np.concatenate([rotation @ velocity[:3], rotation @ velocity[3:]])


# ---------------------------------------------------------------------------------------------------
# The via-point path
# ---------------------------------------------------------------------------------------------------
def minimum_jerk(tau: float) -> tuple[float, float]:
    """Minimum-jerk progress s in [0, 1] and ds/dtau at normalised time tau in [0, 1]."""
    tau = min(max(tau, 0.0), 1.0)
    return 10 * tau**3 - 15 * tau**4 + 6 * tau**5, 30 * tau**2 - 60 * tau**3 + 30 * tau**4


@dataclass(frozen=True)
class ViaPoint:
    """A via point of the paddle's path: position, velocity, yaw, pitch and their rates (world frame)."""

    position_m: np.ndarray  # paddle centre, world
    velocity_m_s: np.ndarray
    yaw_rad: float  # blade turned about world z from its home orientation
    yaw_rate_rad_s: float
    pitch_rad: float = 0.0  # blade face turned up about its horizontal axis (before the yaw)
    pitch_rate_rad_s: float = 0.0

    def rotation(self, home_rotation: np.ndarray) -> np.ndarray:
        """The blade's orientation: pitched up about world y, then yawed about world z, from home."""
        return world_spec.yaw_rotation(self.yaw_rad) @ pin.utils.rpyToMatrix(0.0, -self.pitch_rad, 0.0) @ home_rotation

    def angular_velocity_rad_s(self) -> np.ndarray:
        """World angular velocity of the blade moving with the via-point."""
        pitch_axis_rate = world_spec.yaw_rotation(self.yaw_rad) @ np.array([0.0, -self.pitch_rate_rad_s, 0.0])
        return np.array([0.0, 0.0, self.yaw_rate_rad_s]) + pitch_axis_rate


def turned_about_base(points_m: np.ndarray, turn_rad: float) -> np.ndarray:
    """World points [K, 3] turned by turn_rad about the vertical through the robot base (the shoulder pan's
    axis: world_spec places the base upright)."""
    if turn_rad == 0.0:
        return np.asarray(points_m, dtype=float)  # bit for bit: the unturned takes recorded before the turn
    base = np.array(world_spec.ROBOT_BASE_POSITION_M)
    return base + (np.asarray(points_m, dtype=float) - base) @ world_spec.yaw_rotation(turn_rad).T


def check_side_reach(swing: str, config: TeacherConfig) -> None:
    """A leftward or rightward stroke reaches at most MAX_SIDE_REACH_M further to its side (a forward one
    is never carried sideways)."""
    limit_m = MAX_SIDE_REACH_M.get(swing)
    if limit_m is not None and config.side_reach_m > limit_m:
        raise ValueError(
            f'side_reach_m: a {swing} stroke reaches at most {limit_m} m further to its side, '
            f'got {config.side_reach_m!r}'
        )


class StrokePath:
    """Via-point of the paddle centre over time for one take of a stroke, starting at the ready (home) pose."""

    def __init__(
        self,
        swing: str,
        config: TeacherConfig,
        home_position_m: np.ndarray,
        variation: SwingVariation = SwingVariation(),
        shape: StrokeShape | None = None,
    ):
        """`shape`: the stroke's key poses (default: the shipped STROKES[swing]; stroke_styles reads others)."""
        if swing not in STROKES:
            raise ValueError(f'swing must be one of {SWINGS}, got {swing!r}')
        variation.validate()
        self.nominal_shape = STROKES[swing] if shape is None else shape
        shape = varied_shape(self.nominal_shape, variation)
        self.config = config
        self.variation = variation
        self.backswing_s = config.backswing_s * variation.backswing_scale
        self.forward_swing_s = config.forward_swing_s * variation.forward_swing_scale
        self.ready = np.asarray(home_position_m, dtype=float)
        turn_rad = SIDE_SIGN[swing] * config.side_turn_rad
        check_side_reach(swing, config)
        reach_m = np.array([0.0, SIDE_SIGN[swing] * config.side_reach_m, 0.0])
        swing_points_m = turned_about_base(
            self.ready + reach_m + np.array([shape.back_offset_m, shape.hit_offset_m, shape.follow_offset_m]), turn_rad
        )
        self.back, self.hit, self.follow = swing_points_m
        self.yaws = (0.0, shape.back_yaw_rad + turn_rad, shape.hit_yaw_rad + turn_rad, shape.follow_yaw_rad + turn_rad)
        # The forward swing is the quadratic through back (u=0), hit (u=h) and follow-through (u=1) in its
        # path parameter u; its coefficients (rows: 1, u, u^2) are built once, since `at` runs several
        # times per 500 Hz tick. Lagrange basis: (u-h)(u-1)/h, u(u-1)/(h(h-1)), u(u-h)/(1-h).
        h = variation.hit_fraction
        lagrange = np.array(
            [
                [1.0, 0.0, 0.0],
                [-(1.0 + h) / h, -1.0 / (h * (h - 1.0)), -h / (1.0 - h)],
                [1.0 / h, 1.0 / (h * (h - 1.0)), 1.0 / (1.0 - h)],
            ]
        )
        self._swing_coefficients_m = lagrange @ swing_points_m
        self._swing_yaw_coefficients_rad = lagrange @ np.array(self.yaws[1:])
        # Without key-pose pitches the blade is held at blade_pitch_rad through the forward swing (the
        # shipped strokes, computed as before); with them it turns along the same quadratic as the yaw.
        self.pitches = shape.pitch_rad
        self._swing_pitch_coefficients_rad = None if shape.pitch_rad is None else lagrange @ np.array(shape.pitch_rad)
        self._hit_tau = minimum_jerk_time(h)  # u = h is reached at this fraction of the forward swing

    @property
    def stroke_s(self) -> float:
        """Back-swing, forward swing and follow-through of this take."""
        return self.backswing_s + self.forward_swing_s

    @property
    def duration_s(self) -> float:
        return self.config.lead_in_s + self.stroke_s + self.config.end_hold_s

    def hit_time_s(self) -> float:
        return self.config.lead_in_s + self.backswing_s + self._hit_tau * self.forward_swing_s

    def at(self, t_s: float) -> ViaPoint:
        """The via-point t_s into the clip (lead-in, stroke, end hold)."""
        t_s = t_s - self.config.lead_in_s
        if t_s < 0.0:
            return ViaPoint(self.ready.copy(), np.zeros(3), 0.0, 0.0)
        if t_s < self.backswing_s:
            s, ds = minimum_jerk(t_s / self.backswing_s)
            ds /= self.backswing_s
            _, yaw_back, _, _ = self.yaws
            # opened with the back-swing (to blade_pitch_rad, held open after it, or to the back pose's pitch)
            pitch = self.config.blade_pitch_rad if self.pitches is None else self.pitches[0]
            return ViaPoint(
                self.ready + s * (self.back - self.ready),
                ds * (self.back - self.ready),
                s * yaw_back,
                ds * yaw_back,
                s * pitch,
                ds * pitch,
            )
        # Forward swing: u(t) minimum-jerk from 0 to 1 along the quadratic.
        u, du = minimum_jerk((t_s - self.backswing_s) / self.forward_swing_s)
        du /= self.forward_swing_s
        powers = np.array([1.0, u, u * u])
        dpowers = np.array([0.0, 1.0, 2.0 * u])
        points, yaws = self._swing_coefficients_m, self._swing_yaw_coefficients_rad
        if self._swing_pitch_coefficients_rad is None:
            return ViaPoint(
                powers @ points,
                du * (dpowers @ points),
                float(powers @ yaws),
                float(du * (dpowers @ yaws)),
                self.config.blade_pitch_rad,
            )
        pitches = self._swing_pitch_coefficients_rad
        return ViaPoint(
            powers @ points,
            du * (dpowers @ points),
            float(powers @ yaws),
            float(du * (dpowers @ yaws)),
            float(powers @ pitches),
            float(du * (dpowers @ pitches)),
        )


# ---------------------------------------------------------------------------------------------------
# The hand
# ---------------------------------------------------------------------------------------------------
def clamp_norm(vector: np.ndarray, limit: float) -> np.ndarray:
    """The vector scaled down to norm `limit` if it is longer."""
    norm = float(np.linalg.norm(vector))
    return vector if norm <= limit else vector * (limit / norm)


def hand_wrench(
    config: TeacherConfig,
    position_m: np.ndarray,
    rotation: np.ndarray,
    twist: np.ndarray,
    target_position_m: np.ndarray,
    target_rotation: np.ndarray,
    target_twist: np.ndarray,
) -> np.ndarray:
    """The hand's wrench (force N, torque N m about the gripped point; world axes).

    A spring-damper pulling the gripped point and the blade's orientation towards the via-point, plus
    the push a person makes ahead of the motion to overcome the arm's felt damping.
    """
    c = config
    force = (
        c.hand_stiffness_n_per_m * (target_position_m - position_m)
        + c.hand_damping_ns_per_m * (target_twist[:3] - twist[:3])
        + c.expected_damping_ns_per_m * target_twist[:3]
    )
    torque = (
        c.hand_rot_stiffness_nm_per_rad * pin.log3(target_rotation @ rotation.T)
        + c.hand_rot_damping_nms_per_rad * (target_twist[3:] - twist[3:])
        + c.expected_rot_damping_nms_per_rad * target_twist[3:]
    )
    return np.concatenate([clamp_norm(force, c.max_force_n), clamp_norm(torque, c.max_torque_nm)])


class VirtualTeacher:
    """Approach the ready pose, wait to be started, play the stroke, hold, release.

    Phases: 'approach' -> 'ready' (holding; `begin_stroke` starts the stroke) -> 'stroke' -> 'finished'
    (holding the follow-through; `release` lets go) -> 'released'. `update` gives the hand's wrench
    for the measured joint state at time t; the wrench acts at `grip_frame` (what the simulator does
    with /sim/hand_wrench) while the stroke is defined for the paddle centre.
    """

    def __init__(
        self,
        swing: str,
        config: TeacherConfig = TeacherConfig(),
        grip_frame: str = robot_model.TOOL_FRAME,
        variation: SwingVariation = SwingVariation(),
        shape: StrokeShape | None = None,
    ):
        config.validate()
        self.config = config
        self.swing = swing
        self.kinematics = CellKinematics()
        self.centre_id = self.kinematics.frame_id(robot_model.PADDLE_CENTRE_FRAME)
        self.grip_id = self.kinematics.frame_id(grip_frame)
        home = np.array(world_spec.HOME_JOINT_POSITIONS_RAD)
        home_centre = self.kinematics.pose(home, self.centre_id)
        self.home_rotation = home_centre.rotation.copy()
        # Both frames are fixed to the last link: the grip's pose relative to the paddle centre is constant.
        self.centre_to_grip = home_centre.actInv(self.kinematics.pose(home, self.grip_id))
        self.path = StrokePath(swing, config, home_centre.translation, variation, shape)
        self.phase = 'approach'
        self._phase_start_s: float | None = None
        self._approach_from: ViaPoint | None = None
        self._approach_s = config.approach_min_s
        self._stroke_clock_s = 0.0  # time along the stroke's path; slower than t when the arm lags
        self._stroke_rate = 1.0
        self._last_update_s: float | None = None

    # --- the moving target of the paddle centre ---
    def via_point(self, t_s: float) -> ViaPoint:
        elapsed = t_s - self._phase_start_s
        if self.phase == 'approach':
            start, ready = self._approach_from, self.path.at(0.0)
            s, ds = minimum_jerk(elapsed / self._approach_s)
            ds /= self._approach_s
            return ViaPoint(
                start.position_m + s * (ready.position_m - start.position_m),
                ds * (ready.position_m - start.position_m),
                start.yaw_rad + s * (ready.yaw_rad - start.yaw_rad),
                ds * (ready.yaw_rad - start.yaw_rad),
            )
        if self.phase == 'ready':
            return self.path.at(0.0)
        if self.phase == 'stroke':
            via = self.path.at(min(self._stroke_clock_s, self.path.duration_s))
            return ViaPoint(
                via.position_m,
                self._stroke_rate * via.velocity_m_s,
                via.yaw_rad,
                self._stroke_rate * via.yaw_rate_rad_s,
                via.pitch_rad,
                self._stroke_rate * via.pitch_rate_rad_s,
            )
        return self.path.at(self.path.duration_s)

    def _advance_stroke_clock(self, t_s: float, centre_position_m: np.ndarray) -> None:
        c = self.config
        lag_m = float(np.linalg.norm(centre_position_m - self.path.at(self._stroke_clock_s).position_m))
        self._stroke_rate = min(1.0, max(0.0, (c.lag_stop_m - lag_m) / (c.lag_stop_m - c.lag_slowdown_m)))
        self._stroke_clock_s += self._stroke_rate * max(0.0, t_s - self._last_update_s)

    def _yaw_of(self, rotation: np.ndarray) -> float:
        """Yaw about world z taking the home blade orientation to `rotation` (its vertical-axis part)."""
        relative = rotation @ self.home_rotation.T
        return math.atan2(relative[1, 0], relative[0, 0])

    # --- control ---
    def update(self, t_s: float, q: np.ndarray, qdot: np.ndarray) -> np.ndarray:
        """Hand wrench (world axes, force N and torque N m about the grip point) for this joint state."""
        kin = self.kinematics
        centre = kin.pose(q, self.centre_id)
        if self._phase_start_s is None:  # the first joint state: start the approach from here
            self._phase_start_s = t_s
            self._approach_from = ViaPoint(centre.translation.copy(), np.zeros(3), self._yaw_of(centre.rotation), 0.0)
            distance = float(np.linalg.norm(self.path.at(0.0).position_m - centre.translation))
            angle = abs(self._approach_from.yaw_rad)
            self._approach_s = max(self.config.approach_min_s, distance / self.config.approach_speed_m_s, angle / 0.5)
        if self.phase == 'released':
            return np.zeros(6)
        if self.phase == 'stroke':
            self._advance_stroke_clock(t_s, centre.translation)
        self._last_update_s = t_s
        via = self.via_point(t_s)
        if self.phase == 'approach' and t_s - self._phase_start_s >= self._approach_s:
            self.phase, self._phase_start_s = 'settling', t_s
        if self.phase == 'settling':
            if self.at_rest_on(q, qdot, self.path.at(0.0)) or t_s - self._phase_start_s > self.config.settle_timeout_s:
                self.phase, self._phase_start_s = 'ready', t_s
        if self.phase == 'stroke' and self._stroke_clock_s >= self.path.duration_s:
            self.phase, self._phase_start_s = 'finished', t_s
        if self.phase == 'settling':
            via = self.path.at(0.0)
        target_centre = pin.SE3(via.rotation(self.home_rotation), via.position_m)
        target_grip = target_centre * self.centre_to_grip
        omega = via.angular_velocity_rad_s()
        # Velocity of the gripped point on a body moving with the via-point: v + omega x r.
        lever = target_grip.translation - target_centre.translation
        target_twist = np.concatenate([via.velocity_m_s + np.cross(omega, lever), omega])
        grip = kin.pose(q, self.grip_id)
        return hand_wrench(
            self.config,
            grip.translation,
            grip.rotation,
            kin.twist(q, qdot, self.grip_id),
            target_grip.translation,
            target_grip.rotation,
            target_twist,
        )

    def at_rest_on(self, q: np.ndarray, qdot: np.ndarray, via: ViaPoint) -> bool:
        centre = self.kinematics.pose(q, self.centre_id)
        target_rotation = via.rotation(self.home_rotation)
        c = self.config
        return (
            np.linalg.norm(centre.translation - via.position_m) < c.settle_position_m
            and np.linalg.norm(pin.log3(target_rotation @ centre.rotation.T)) < c.settle_angle_rad
            and np.linalg.norm(self.kinematics.twist(q, qdot, self.centre_id)[:3]) < c.settle_speed_m_s
        )

    def begin_stroke(self, t_s: float) -> None:
        if self.phase != 'ready':
            raise RuntimeError(f'the stroke can start only from the ready pose (phase {self.phase})')
        self.phase, self._phase_start_s = 'stroke', t_s
        self._stroke_clock_s, self._stroke_rate = 0.0, 1.0

    def release(self) -> None:
        self.phase = 'released'
