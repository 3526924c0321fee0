"""How the blade meets the ball: an actor's contacts beside its demonstrations' hits.

Much of a stroke's DTW distance from the demonstrations is set where it meets the ball: the arm must put
the blade at the ball, facing where the ball has to go, and every frame around the contact pays for the
pose that takes (docs/DESIGN.md, Known limits, says what moving the contact did and did not do). This
module measures the blade at each contact, for an actor's strokes (the frame after its first paddle contact,
`Stroke.hit_frame`) and for demonstrations (which hold no ball: each original clip's `dataset.hit_frame`,
the fastest frame of its last swing).

The blade, from the paddle centre's pose in the world (batched_kinematics.forward_kinematics; n is the
blade's face normal, the frame's z axis, which faces the net at the home pose):
  ahead_m      the paddle centre's x minus its x at the home pose (m): how far in front of home it meets
               the ball (+: towards the net)
  opening_deg  asin(n_z): 0 a vertical blade, + a face turned up to the sky
  facing_deg   atan2(n_y, n_x): 0 square to the table, + turned towards the robot's left (world +y)
  speed_m_s    the paddle centre's speed: how fast the blade meets the ball. An actor's over the frame that
               ends at its contact (the strokes hold positions); a set's from its clips' joint velocities at
               the hit, at the dataset's fastest speed-up (x5 in the paper's), the fastest it offers
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from stylepong_description.robot_cell import POLICY_RATE_HZ
from stylepong_policy.evaluation.strokes import DIRECTIONS, Stroke, paddle_home_position_m


@dataclass(frozen=True)
class Blade:
    """The blade at one contact."""

    ahead_m: float
    opening_deg: float
    facing_deg: float
    speed_m_s: float


BLADE_FIELDS = ('ahead_m', 'opening_deg', 'facing_deg', 'speed_m_s')


def _paddle_poses(q_rad: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The paddle centre [3, K] (m) and its face normal [3, K] in the world at each row of q_rad [K, 6]."""
    import torch

    from stylepong_sim.batched import batched_kinematics

    kin = batched_kinematics.forward_kinematics(
        batched_kinematics.build_arm_model(dtype=torch.float64), torch.as_tensor(q_rad.T, dtype=torch.float64)
    )
    return kin.paddle_pos_m.numpy(), kin.paddle_rot[:, 2].numpy()


def blades(q_rad: np.ndarray, qd_rad_s: np.ndarray) -> list[Blade]:
    """The blade at each joint configuration of q_rad [K, 6] (K >= 0), moving at the joint velocities
    qd_rad_s [K, 6]."""
    q = np.asarray(q_rad, dtype=float).reshape(-1, 6)
    qd = np.asarray(qd_rad_s, dtype=float).reshape(-1, 6)
    if len(q) != len(qd):
        raise ValueError(f'{len(q)} configurations but {len(qd)} joint velocities')
    if not len(q):
        return []
    position, normal = _paddle_poses(q)
    # The paddle's velocity J(q) qd, as the difference over a step short enough to be linear (0.1 ms).
    step_s = 1e-4
    speed_m_s = np.linalg.norm(_paddle_poses(q + step_s * qd)[0] - position, axis=0) / step_s
    home_x = paddle_home_position_m()[0]
    return [
        Blade(
            ahead_m=float(position[0, k] - home_x),
            opening_deg=math.degrees(math.asin(max(-1.0, min(1.0, float(normal[2, k]))))),
            facing_deg=math.degrees(math.atan2(float(normal[1, k]), float(normal[0, k]))),
            speed_m_s=float(speed_m_s[k]),
        )
        for k in range(q.shape[0])
    ]


def actor_contacts(strokes: Iterable[Stroke]) -> dict[str, list[Blade]]:
    """The blade at each stroke's first paddle contact, by the stroke's direction (strokes that never hit
    have none)."""
    hitting = [s for s in strokes if s.hit and 1 <= s.hit_frame < len(s.joint_positions_rad)]
    at = np.array([s.joint_positions_rad[s.hit_frame] for s in hitting]).reshape(-1, 6)
    before = np.array([s.joint_positions_rad[s.hit_frame - 1] for s in hitting]).reshape(-1, 6)
    found = blades(at, (at - before) * POLICY_RATE_HZ)  # the strokes hold positions only
    by_direction: dict[str, list[Blade]] = {}
    for stroke, blade in zip(hitting, found):
        by_direction.setdefault(stroke.direction, []).append(blade)
    return by_direction


def demonstrated_contacts(dataset) -> dict[str, list[Blade]]:
    """The blade at each original clip's hit (dataset.hit_frame), by label; speed-ups repeat their original
    and move it faster: the speed is the original's at the dataset's fastest speed-up."""
    from stylepong_policy.training.dataset import hit_frame

    originals = dataset.select(speed_factors=[1])
    frames = [int(dataset.clip_start[c]) + hit_frame(dataset.clip(c).qd) for c in originals]
    fastest = float(np.max(dataset.speed_factor)) if len(dataset.speed_factor) else 1.0
    found = blades(dataset.q[frames], fastest * dataset.qd[frames])
    by_label: dict[str, list[Blade]] = {}
    for clip, blade in zip(originals, found):
        by_label.setdefault(str(dataset.label[clip]), []).append(blade)
    return by_label


def mean_blades(contacts: Mapping[str, Sequence[Blade]]) -> dict[str, dict[str, float] | None]:
    """Per direction: the mean of each blade field and the number of contacts (None: no contact)."""
    means: dict[str, dict[str, float] | None] = {}
    for direction in DIRECTIONS:
        found = contacts.get(direction, [])
        means[direction] = (
            (
                {name: float(np.mean([getattr(b, name) for b in found])) for name in BLADE_FIELDS}
                | {'contacts': len(found)}
            )
            if found
            else None
        )
    return means


def blade_difference(blade: Mapping[str, float] | None, reference: Mapping[str, float] | None) -> dict | None:
    """Each of BLADE_FIELDS of a mean blade (mean_blades' entry) minus the reference's; None when either had
    no contact."""
    if blade is None or reference is None:
        return None
    return {name: blade[name] - reference[name] for name in BLADE_FIELDS}


def difference_text(difference: Mapping[str, float]) -> str:
    """A blade_difference in words, with the units of contact_table's columns."""
    return (
        f'ahead {_signed(difference["ahead_m"], 2)} m, opening {_signed(difference["opening_deg"], 0)} deg, '
        f'facing {_signed(difference["facing_deg"], 0)} deg, speed {_signed(difference["speed_m_s"], 2)} m/s'
    )


TABLE_NOTE = (
    "The mean over each direction's contacts: an actor's at its strokes' first paddle contact, a set "
    "of demonstrations' at each original clip's hit (its fastest frame; the clips hold no ball). Ahead "
    "of home: the paddle centre's x beyond its home pose (towards the net); opening: the face turned up "
    "from vertical; facing: the face turned towards the robot's left (world +y) from square to the table; "
    "blade speed: the paddle centre's, an actor's over the frame that ends at its contact, a set's "
    'at its fastest speed-up (`stylepong_policy.evaluation.contacts`).'
)


def contact_table(rows: Mapping[str, Mapping[str, dict | None]]) -> tuple[list[str], list[list[str]]]:
    """Markdown table (header, rows) of mean blades: one row per (name, direction) with contacts."""
    header = [
        'strokes',
        'direction',
        'ahead of home (m)',
        'opening (deg)',
        'facing (deg)',
        'blade speed (m/s)',
        'contacts',
    ]
    body = []
    for name, by_direction in rows.items():
        for direction in DIRECTIONS:
            mean = by_direction.get(direction)
            if mean is not None:
                body.append(
                    [
                        name,
                        direction,
                        _signed(mean['ahead_m'], 2),
                        _signed(mean['opening_deg'], 0),
                        _signed(mean['facing_deg'], 0),
                        f'{mean["speed_m_s"]:.2f}',
                        str(mean['contacts']),
                    ]
                )
    return header, body


def _signed(value: float, digits: int) -> str:
    """The value with its sign, rounded; a value that rounds to zero is +0 (never -0)."""
    return f'{round(value, digits) + 0.0:+.{digits}f}'
