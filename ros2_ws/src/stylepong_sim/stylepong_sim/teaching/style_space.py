"""The space of a person's stroke styles: style files drawn at random, for tuning and held-out sets (no rclpy).

The hand-made styles (config/styles/*.yaml) were the sets the recipe was tuned on, so a figure measured on
them is no longer a fair test. A protocol that cannot overfit draws its styles instead: from ranges wide
enough to hold every hand-made style (test_style_space.py checks that the ranges bracket their key poses),
each draw kept only if every take the recording will drag passes the rules the hand-made styles meet
(stroke_styles.check_stroke, used as it is: a drawn style is never held to looser rules).

StyleParameters are what one person's strokes differ in; `key_poses` turns them into a style file's
mappings (stroke_styles' shape: back_offset_m, hit_offset_m, follow_offset_m, yaw_rad, pitch_rad per
swing). Every key-pose coordinate is one parameter or a fixed sum of a few, so the box of parameter ranges
maps onto a box of key poses whose corners are easy to compute. Offsets are of the paddle centre from home
in world axes (x towards the opponent, y to the robot's left, z up), as in teacher.StrokeShape.

Not in the space: the waiting (ready) pose. The teacher starts every stroke from home (StrokePath.ready is
world_spec's home pose) and a style file has no key for another one, so a drawn style cannot move it.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from stylepong_common.settings import check_ranges, declared_range, within
from stylepong_sim.teaching import stroke_styles
from stylepong_sim.teaching.teacher import (
    SIDE_SIGN,
    STROKES,
    SWINGS,
    StrokePath,
    SwingVariation,
    TeacherConfig,
    sample_variation,
)

# The order tools/record_demos.sh records a set in (demonstrations/README.md): clip N gets the teacher's
# seed N (SEED_OFFSET 0), so these seven seeds are the takes a recorded set drags.
RECORDING_ORDER = ('forward', 'leftward', 'rightward', 'forward', 'leftward', 'rightward', 'forward')
RECORDED_SEEDS = tuple(range(1, len(RECORDING_ORDER) + 1))

# Where a sideways hit is met along x, relative to the forward hit: the hand-made and shipped strokes meet
# the leftward ball 0.01-0.03 m and the rightward one 0-0.02 m nearer home than the forward one (reaching
# to the side the hand comes back; on the left sooner, where the arm's reach ends sooner).
SIDE_HIT_BEHIND_FORWARD_M = {'leftward': 0.02, 'rightward': 0.005}
# The share of the forward follow-through's length (hit to follow-through along x) a sideways stroke
# carries forwards; it spends the rest sweeping to its side. The hand-made styles: about a half leftward,
# about 0.7 rightward (the left follow-through is nearer the arm's reach, teacher.STROKES).
SIDE_FOLLOW_SHARE = {'leftward': 0.5, 'rightward': 0.7}
# A sideways stroke's wrist winds up from a blade already turned this far towards its side: its back-swing
# yaw is side * (this - wrist_windup_rad), within 0.05 rad of every hand-made style's.
SIDE_WINDUP_START_RAD = 0.15
# Rounding of drawn values: a person's key poses are not known better than a millimetre or a milliradian,
# and a style file in round numbers reads back exactly as it was checked.
DECIMALS = {'_s': 2, '_m': 3, '_rad': 3}
KEY_POSE_DECIMALS = 4  # key poses are sums of drawn values: rounded again to drop float noise (0.1 mm)
# What the defaults are read from: the shipped strokes and the shipped teacher's tempo and blade opening.
_FORWARD, _LEFTWARD, _SHIPPED = STROKES['forward'], STROKES['leftward'], TeacherConfig()


@dataclass(frozen=True)
class StyleParameters:
    """One person's stroke style. Defaults: the shipped strokes (teacher.STROKES; the forward one exactly, the
    sideways ones about), tempo and blade opening (TeacherConfig), which the checks refuse: the blade opened
    from the back-swing on takes the leftward wrist within 0.034 m of the shoulder singularity (teacher.py).

    Every range covers the four hand-made styles (compact, lift, long, wristy) and the shipped strokes;
    where a value beyond them would break the checks for most draws, the range ends there.
    """

    # Tempo of a careful drag of a UR5 (about 1 rad/s at the fastest joint): the shipped 0.8/1.6 s is the
    # brisk end, the long set's 1.6/3.0 s the slow one; compact's 1.2 s forward swing is the quickest.
    # Takes scale both by 0.8-1.2, which keeps every stroke within teacher.STROKE_S_RANGE.
    backswing_s: float = within(_SHIPPED.backswing_s, 0.8, 1.6)
    forward_swing_s: float = within(_SHIPPED.forward_swing_s, 1.2, 3.0)
    # Where the back-swing turns, and so its amplitude: how far behind home (compact 0.04, long 0.16 m;
    # beyond that the wrist nears the shoulder singularity), how low (compact 0.02, lift 0.10 m) and how
    # far to the right a forward back-swing winds up (compact 0.02, long 0.10 m).
    backswing_depth_m: float = within(-_FORWARD.back_offset_m[0], 0.03, 0.16)
    backswing_drop_m: float = within(-_FORWARD.back_offset_m[2], 0.01, 0.11)
    backswing_width_m: float = within(-_FORWARD.back_offset_m[1], 0.01, 0.1)
    # How far a sideways back-swing winds up across the body (a leftward one to the right, a rightward one
    # to the left); below zero it starts on its own side already (compact, lift).
    side_windup_m: float = within(-_LEFTWARD.back_offset_m[1], -0.03, 0.12)
    # The hit: how far in front of home and above it the forward ball is met (every style 0.04-0.08 m and
    # 0.02-0.05 m), and how far to its side a sideways one (0.12-0.19 m; the label check wants 0.09 m).
    hit_ahead_m: float = within(_FORWARD.hit_offset_m[0], 0.04, 0.08)
    hit_height_m: float = within(_FORWARD.hit_offset_m[2], 0.01, 0.06)
    side_hit_m: float = within(_LEFTWARD.hit_offset_m[1], 0.11, 0.2)
    # How far the follow-through goes: along x beyond the forward hit (compact 0.04, long 0.22 m), and beyond
    # a sideways hit to its side (compact 0.06, long 0.19 m); a forward stroke drifts a little to the right
    # (0.01-0.05 m).
    follow_through_m: float = within(_FORWARD.follow_offset_m[0] - _FORWARD.hit_offset_m[0], 0.03, 0.22)
    side_sweep_m: float = within(_LEFTWARD.follow_offset_m[1] - _LEFTWARD.hit_offset_m[1], 0.05, 0.19)
    forward_drift_m: float = within(-_FORWARD.follow_offset_m[1], 0.0, 0.05)
    # Lift: how high above home the follow-through ends (compact 0.06 m; lift, a low-to-high drive, 0.24 m).
    follow_rise_m: float = within(_FORWARD.follow_offset_m[2], 0.05, 0.25)
    # Wrist action, the blade's turn about the vertical: wound up away from the ball at the back-swing
    # (compact 0.08, wristy 0.60 rad), flicked on past the hit (0.06-0.55 rad), and how far a sideways hit
    # faces its side (0.30-0.40 rad; the label check wants 0.2).
    wrist_windup_rad: float = within(-_FORWARD.back_yaw_rad, 0.05, 0.65)
    wrist_flick_rad: float = within(_FORWARD.follow_yaw_rad, 0.05, 0.6)
    side_face_rad: float = within(_LEFTWARD.hit_yaw_rad, 0.25, 0.45)
    # Blade opening (face up) at the back-swing, the hit and the follow-through, the same for every swing as
    # in every hand-made style: opened late (long 0.2 -> 0.7), closing (lift 0.7 -> 0.3) or held (compact
    # 0.4). The hit's stays near the 0.6 rad that returns balls; beyond 1 rad the blade faces the ceiling.
    back_pitch_rad: float = within(_SHIPPED.blade_pitch_rad, 0.1, 0.7)
    hit_pitch_rad: float = within(_SHIPPED.blade_pitch_rad, 0.35, 0.65)
    follow_pitch_rad: float = within(_SHIPPED.blade_pitch_rad, 0.3, 1.0)

    def validate(self) -> None:
        """ValueError naming the first parameter outside its range."""
        check_ranges(self)


def parameter_ranges() -> dict[str, tuple[float, float]]:
    """Each parameter's (low, high), read from StyleParameters' declarations."""
    ranges = {}
    for field in dataclasses.fields(StyleParameters):
        bound = declared_range(field)
        ranges[field.name] = (bound.low, bound.high)
    return ranges


def _decimals(name: str) -> int:
    return next(places for suffix, places in DECIMALS.items() if name.endswith(suffix))


def draw_style(rng: np.random.Generator) -> StyleParameters:
    """One style drawn uniformly from every range, independently (a person's traits are not tied)."""
    values = {
        name: round(float(rng.uniform(low, high)), _decimals(name)) for name, (low, high) in parameter_ranges().items()
    }
    return StyleParameters(**values)


def _rounded(values) -> list[float]:
    return [round(float(v), KEY_POSE_DECIMALS) + 0.0 for v in values]  # + 0.0: no -0.0 in a file


def swing_key_poses(p: StyleParameters, swing: str) -> dict[str, list[float]]:
    """One swing's mapping of a style file (back_offset_m, hit_offset_m, follow_offset_m, yaw_rad, pitch_rad)."""
    side = SIDE_SIGN[swing]  # 0 forward, +1 leftward, -1 rightward
    pitch = [p.back_pitch_rad, p.hit_pitch_rad, p.follow_pitch_rad]
    if side == 0.0:
        back = [-p.backswing_depth_m, -p.backswing_width_m, -p.backswing_drop_m]
        hit = [p.hit_ahead_m, 0.0, p.hit_height_m]
        follow = [p.hit_ahead_m + p.follow_through_m, -p.forward_drift_m, p.follow_rise_m]
        yaw = [-p.wrist_windup_rad, 0.0, p.wrist_flick_rad]
    else:
        hit_x_m = p.hit_ahead_m - SIDE_HIT_BEHIND_FORWARD_M[swing]
        back = [-p.backswing_depth_m, -side * p.side_windup_m, -p.backswing_drop_m]
        hit = [hit_x_m, side * p.side_hit_m, p.hit_height_m]
        follow = [
            hit_x_m + SIDE_FOLLOW_SHARE[swing] * p.follow_through_m,
            side * (p.side_hit_m + p.side_sweep_m),
            p.follow_rise_m,
        ]
        yaw = [
            side * (SIDE_WINDUP_START_RAD - p.wrist_windup_rad),
            side * p.side_face_rad,
            side * (p.side_face_rad + p.wrist_flick_rad),
        ]
    return dict(
        zip(stroke_styles.KEYS, (_rounded(back), _rounded(hit), _rounded(follow), _rounded(yaw), _rounded(pitch)))
    )


def key_poses(p: StyleParameters) -> dict[str, dict[str, list[float]]]:
    """The style file's document: every swing's key poses (stroke_styles.load_strokes_file reads it)."""
    return {swing: swing_key_poses(p, swing) for swing in SWINGS}


def teacher_config(p: StyleParameters) -> TeacherConfig:
    """The teacher's settings that tools/record_demos.sh passes for this style (the tempo; the rest default)."""
    return TeacherConfig(backswing_s=p.backswing_s, forward_swing_s=p.forward_swing_s)


def checked_takes(swing: str) -> list[tuple[str, SwingVariation]]:
    """The takes a style must pass for `swing`: the nominal one and seeds 1-7, as test_stroke_styles checks the
    hand-made styles (the seeds a recorded set gives this swing are among them)."""
    return [('nominal', SwingVariation())] + [(f'seed {s}', sample_variation(swing, s)) for s in RECORDED_SEEDS]


def style_problem(p: StyleParameters, kinematics: stroke_styles.StrokeKinematics) -> str | None:
    """Why the style's takes cannot all be dragged (stroke_styles' first refusal); None when every one can."""
    config = teacher_config(p)
    try:
        p.validate()
        config.validate()
    except ValueError as error:
        return str(error)
    home_m = kinematics.kin.pose(kinematics.home_q, kinematics.centre).translation
    for swing, entry in key_poses(p).items():
        try:  # the file's own limits (offsets within reach, angles, an opening pitch)
            shape = stroke_styles.shape_from_mapping(entry, swing)
        except ValueError as error:
            return str(error)
        for take, variation in checked_takes(swing):
            try:
                stroke_styles.check_stroke(swing, StrokePath(swing, config, home_m, variation, shape), kinematics)
            except ValueError as error:
                return f'{swing} {take}: {error}'
    return None


@dataclass(frozen=True)
class CheckedStyle:
    """A style that passed every check, and why each draw before it was refused."""

    parameters: StyleParameters
    rejections: tuple[str, ...]


def draw_checked_style(
    rng: np.random.Generator, kinematics: stroke_styles.StrokeKinematics | None = None, max_draws: int = 1000
) -> CheckedStyle:
    """Draw until a style passes style_problem; RuntimeError after max_draws refusals (the space is wrong)."""
    kinematics = kinematics or stroke_styles.StrokeKinematics()
    rejections = []
    for _ in range(max_draws):
        parameters = draw_style(rng)
        problem = style_problem(parameters, kinematics)
        if problem is None:
            return CheckedStyle(parameters, tuple(rejections))
        rejections.append(problem)
    raise RuntimeError(f'no style out of {max_draws} draws passed the checks; the last: {rejections[-1]}')


def split_tuning_heldout(
    names: list[str], rng: np.random.Generator, heldout_share: float = 0.5
) -> dict[str, list[str]]:
    """A seeded shuffle of the styles into 'tuning' and 'heldout' (the held-out ones rounded down, at least one
    of each when there are two or more styles)."""
    if not 0.0 < heldout_share < 1.0:
        raise ValueError(f'heldout_share must be within 0-1 (both excluded), got {heldout_share!r}')
    shuffled = [names[i] for i in rng.permutation(len(names))]
    heldout = min(max(int(len(names) * heldout_share), 1), len(names) - 1) if len(names) > 1 else 0
    held = set(shuffled[:heldout])
    return {'tuning': [n for n in names if n not in held], 'heldout': [n for n in names if n in held]}
