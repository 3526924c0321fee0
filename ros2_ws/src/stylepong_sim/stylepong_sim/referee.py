"""The rally referee: the evaluation protocol (docs/DESIGN.md, "Evaluation protocol") as a small
state machine, free of ROS.

A simulator reports what happens to the ball it launched (contacts, its state every physics step);
the referee turns that into the ball's RallyEvent sequence. The rules themselves are functions of
arrays (`table_contact_verdicts`, `ball_state_verdicts` and their helpers: Python floats and bools,
numpy arrays and torch tensors alike), so the MuJoCo cell's Referee here and the batched training
world, which judges N balls at once in torch, apply the same code.

Events (codes: stylepong_msgs/RallyEvent's constants):
  LAUNCHED                at launch.
  BOUNCE_OWN_SIDE         the ball touches the table top with x < 0 (the robot's half).
  BOUNCE_OPPONENT_SIDE    the ball touches the table top with x >= 0.
  PADDLE_HIT              the ball touches the paddle's blade (either face or its rim).
  NET                     the ball touches the net.
  ROBOT_CONTACT           the ball touches any other part of the robot (the paddle's handle included).
  TABLE_CONTACT_BY_ROBOT  any robot geometry touches the table or the net (position: the contact point).
  OUT                     a returned ball can no longer reach the table top (see below).
  TIMEOUT                 BALL_TIMEOUT_S after the launch without a verdict.
  RALLY_END               the verdict: exactly one per launched ball, always the ball's last event,
                          with `success` and a snake_case `reason`.
`position` is the ball centre at the event (TABLE_CONTACT_BY_ROBOT: the contact point).

Rules, applied in the order the events happen (the first that gives a verdict ends the rally):
  Before the paddle has touched the ball:
    - a first BOUNCE_OWN_SIDE is expected and fine; a second one ends it:       'second_bounce_own_side'
    - BOUNCE_OPPONENT_SIDE and NET are recorded and judged by what follows (the serve's business).
    - ROBOT_CONTACT:                                                             'robot_contact'
    - the ball is dead (its bottom reaches the floor, or its centre leaves the cell): 'no_hit'
  The first PADDLE_HIT starts the return. After it:
    - the first table contact decides: BOUNCE_OPPONENT_SIDE -> success          'returned'
                                       BOUNCE_OWN_SIDE      -> failure          'own_side'
    - NET (a ball touching the net before its first table contact):             'net'
    - a second PADDLE_HIT:                                                       'double_hit'
    - ROBOT_CONTACT:                                                             'robot_contact'
    - OUT: the ball is dead, or its bottom is below the table top outside the table's footprint
      while falling (from there it can only fall further):                      'out'
  At any time before the verdict:
    - TABLE_CONTACT_BY_ROBOT:                                                    'table_contact_by_robot'
    - TIMEOUT (time since launch >= BALL_TIMEOUT_S):                             'timeout'
    - the ball is removed or replaced (reset, new launch) before a verdict:      'aborted'
A hit before the ball's own-side bounce (a volley) is allowed: the protocol judges the return only.
After RALLY_END the referee stays silent about that ball.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from stylepong_msgs.msg import RallyEvent as RallyEventMessage
from stylepong_sim import world_spec

# The event codes are the interface's: stylepong_msgs/msg/RallyEvent.msg defines them and the referee reads
# them off the generated message class (plain class attributes: reading them loads no ROS runtime, so the
# batched world stays free of ROS), so the cells, the batched world, rally_eval and a bag's reader cannot
# disagree on a number.
LAUNCHED = RallyEventMessage.LAUNCHED
BOUNCE_OWN_SIDE = RallyEventMessage.BOUNCE_OWN_SIDE
PADDLE_HIT = RallyEventMessage.PADDLE_HIT
BOUNCE_OPPONENT_SIDE = RallyEventMessage.BOUNCE_OPPONENT_SIDE
NET = RallyEventMessage.NET
ROBOT_CONTACT = RallyEventMessage.ROBOT_CONTACT
TABLE_CONTACT_BY_ROBOT = RallyEventMessage.TABLE_CONTACT_BY_ROBOT
OUT = RallyEventMessage.OUT
TIMEOUT = RallyEventMessage.TIMEOUT
RALLY_END = RallyEventMessage.RALLY_END

EVENT_NAMES = {
    LAUNCHED: 'LAUNCHED',
    BOUNCE_OWN_SIDE: 'BOUNCE_OWN_SIDE',
    PADDLE_HIT: 'PADDLE_HIT',
    BOUNCE_OPPONENT_SIDE: 'BOUNCE_OPPONENT_SIDE',
    NET: 'NET',
    ROBOT_CONTACT: 'ROBOT_CONTACT',
    TABLE_CONTACT_BY_ROBOT: 'TABLE_CONTACT_BY_ROBOT',
    OUT: 'OUT',
    TIMEOUT: 'TIMEOUT',
    RALLY_END: 'RALLY_END',
}

REASON_RETURNED = 'returned'
REASON_NO_HIT = 'no_hit'
REASON_SECOND_BOUNCE_OWN_SIDE = 'second_bounce_own_side'
REASON_OWN_SIDE = 'own_side'
REASON_NET = 'net'
REASON_DOUBLE_HIT = 'double_hit'
REASON_ROBOT_CONTACT = 'robot_contact'
REASON_OUT = 'out'
REASON_TABLE_CONTACT_BY_ROBOT = 'table_contact_by_robot'
REASON_TIMEOUT = 'timeout'
REASON_ABORTED = 'aborted'

# The verdicts a rule can give, as indices for arrays of balls (the batched world); 'aborted' is not among
# them: only a simulator that removes a ball gives it.
REASONS: tuple[str, ...] = (
    REASON_RETURNED,
    REASON_NO_HIT,
    REASON_SECOND_BOUNCE_OWN_SIDE,
    REASON_OWN_SIDE,
    REASON_NET,
    REASON_DOUBLE_HIT,
    REASON_ROBOT_CONTACT,
    REASON_OUT,
    REASON_TABLE_CONTACT_BY_ROBOT,
    REASON_TIMEOUT,
)
REASON_INDEX = {name: i for i, name in enumerate(REASONS)}
NO_VERDICT = -1
# The event a verdict of the ball's state comes with (a no_hit has none).
_STATE_VERDICT_EVENTS = {REASON_OUT: OUT, REASON_TIMEOUT: TIMEOUT}


@dataclass(frozen=True)
class RallyEvent:
    """An event of a rally (launch, bounce, hit, end); an end carries the verdict and its reason."""

    ball_id: int
    type: int
    time_s: float
    position_m: tuple[float, float, float]
    success: bool = False
    reason: str = ''

    def __str__(self) -> str:
        verdict = f' success={self.success} reason={self.reason}' if self.type == RALLY_END else ''
        return f'ball {self.ball_id} t={self.time_s:.3f} s {EVENT_NAMES[self.type]}{verdict}'


def _xyz(position_m) -> tuple[float, float, float]:
    return (float(position_m[0]), float(position_m[1]), float(position_m[2]))


# --- The rules, on one ball or on arrays of balls -------------------------------------------------------
# A mask is a bool, a numpy bool array or a torch bool tensor; a position is indexable by axis (x, y, z
# first: a sequence, an array [3, ...] or a tensor [3, N]). A rule's verdicts are (reason, mask) pairs in
# the order the rules apply: the first whose mask holds is the verdict.
Mask = Any  # bool | numpy bool array | torch bool tensor
Values = Any  # float | numpy array | torch tensor (one value per ball)
Position = Any  # (x, y, z) sequence | numpy array [3, ...] | torch tensor [3, N]
Verdicts = tuple[tuple[str, Mask], ...]


def logical_not(mask: Mask) -> Mask:
    """Not, for bools, numpy arrays and torch tensors alike (~ on a Python bool gives -2, not False)."""
    return mask ^ True


def ball_is_dead(position_m: Position) -> Mask:
    """The ball's bottom touched the floor or its centre left the cell."""
    return (
        (position_m[2] <= world_spec.BALL_RADIUS_M)
        | (abs(position_m[0]) > world_spec.CELL_HALF_EXTENT_M[0])
        | (abs(position_m[1]) > world_spec.CELL_HALF_EXTENT_M[1])
    )


def ball_cannot_reach_table(position_m: Position, vertical_velocity_m_s: Values) -> Mask:
    """Bottom below the table top, outside the footprint, falling: the table top is out of reach."""
    below_top = position_m[2] - world_spec.BALL_RADIUS_M < world_spec.TABLE_HEIGHT_M
    return below_top & world_spec.off_table(position_m[0], position_m[1]) & (vertical_velocity_m_s < 0.0)


def is_own_side(position_m: Position) -> Mask:
    """A table contact at this ball position is on the robot's half (x < 0)."""
    return position_m[0] < 0.0


def own_side_bounce(hit: Mask, own_side: Mask) -> Mask:
    """A table contact that counts as a bounce on the robot's half: one before the paddle's hit."""
    return own_side & logical_not(hit)


def table_contact_verdicts(hit: Mask, own_side: Mask, own_bounces: Values) -> Verdicts:
    """A table contact's verdicts; own_bounces counts this contact's own_side_bounce already."""
    return (
        (REASON_RETURNED, hit & logical_not(own_side)),
        (REASON_OWN_SIDE, hit & own_side),
        (REASON_SECOND_BOUNCE_OWN_SIDE, own_side_bounce(hit, own_side) & (own_bounces >= 2)),
    )


def net_contact_verdicts(hit: Mask) -> Verdicts:
    """A returned ball touching the net before its first table contact."""
    return ((REASON_NET, hit),)


def paddle_contact_verdicts(hit: Mask) -> Verdicts:
    """The paddle touching a ball it has hit already."""
    return ((REASON_DOUBLE_HIT, hit),)


def ball_state_verdicts(
    hit: Mask, position_m: Position, vertical_velocity_m_s: Values, time_since_launch_s: Values, timeout_s: float
) -> Verdicts:
    """The verdicts of the ball's state after a physics step: a dead ball, an out ball, the timeout."""
    dead = ball_is_dead(position_m)
    out = hit & (dead | ball_cannot_reach_table(position_m, vertical_velocity_m_s))
    return (
        (REASON_NO_HIT, dead & logical_not(hit)),
        (REASON_OUT, out),
        (REASON_TIMEOUT, time_since_launch_s >= timeout_s),
    )


class Referee:
    """Judges one ball at a time. Every method returns the events it produced (possibly none)."""

    def __init__(self, timeout_s: float = world_spec.BALL_TIMEOUT_S):
        self.timeout_s = timeout_s
        self.ball_id: int | None = None
        self._open = False
        self._launch_time_s = 0.0
        self._own_bounces = 0
        self._hit = False

    @property
    def rally_open(self) -> bool:
        """A ball is in play and has no verdict yet."""
        return self._open

    def launch(self, ball_id: int, time_s: float, position_m) -> list[RallyEvent]:
        events = self.abort(time_s, position_m)
        self.ball_id = ball_id
        self._open = True
        self._launch_time_s = time_s
        self._own_bounces = 0
        self._hit = False
        return events + [self._event(LAUNCHED, time_s, position_m)]

    def abort(self, time_s: float, position_m) -> list[RallyEvent]:
        """The ball is removed before a verdict (reset, a new launch)."""
        if not self._open:
            return []
        return [self._end(time_s, position_m, False, REASON_ABORTED)]

    def table_contact(self, time_s: float, position_m) -> list[RallyEvent]:
        if not self._open:
            return []
        own_side = is_own_side(_xyz(position_m))
        event = self._event(BOUNCE_OWN_SIDE if own_side else BOUNCE_OPPONENT_SIDE, time_s, position_m)
        if own_side_bounce(self._hit, own_side):
            self._own_bounces += 1
        return [event] + self._first_verdict(
            time_s, position_m, table_contact_verdicts(self._hit, own_side, self._own_bounces)
        )

    def net_contact(self, time_s: float, position_m) -> list[RallyEvent]:
        if not self._open:
            return []
        event = self._event(NET, time_s, position_m)
        return [event] + self._first_verdict(time_s, position_m, net_contact_verdicts(self._hit))

    def paddle_contact(self, time_s: float, position_m) -> list[RallyEvent]:
        if not self._open:
            return []
        event = self._event(PADDLE_HIT, time_s, position_m)
        verdict = self._first_verdict(time_s, position_m, paddle_contact_verdicts(self._hit))
        self._hit = True
        return [event] + verdict

    def robot_contact(self, time_s: float, position_m) -> list[RallyEvent]:
        return self._losing_contact(ROBOT_CONTACT, REASON_ROBOT_CONTACT, time_s, position_m)

    def robot_table_contact(self, time_s: float, contact_point_m) -> list[RallyEvent]:
        return self._losing_contact(TABLE_CONTACT_BY_ROBOT, REASON_TABLE_CONTACT_BY_ROBOT, time_s, contact_point_m)

    def ball_state(self, time_s: float, position_m, velocity_m_s) -> list[RallyEvent]:
        """Called with the ball's state after every physics step: timeout, dead and out balls."""
        if not self._open:
            return []
        verdicts = ball_state_verdicts(
            self._hit, _xyz(position_m), float(velocity_m_s[2]), time_s - self._launch_time_s, self.timeout_s
        )
        for reason, holds in verdicts:
            if holds:
                event = _STATE_VERDICT_EVENTS.get(reason)
                ended = [self._end(time_s, position_m, False, reason)]
                return ended if event is None else [self._event(event, time_s, position_m)] + ended
        return []

    def _losing_contact(self, event_type: int, reason: str, time_s: float, position_m) -> list[RallyEvent]:
        """A contact that loses the rally at once: its event, then the RALLY_END for `reason` (nothing once the
        rally is over)."""
        if not self._open:
            return []
        return [self._event(event_type, time_s, position_m), self._end(time_s, position_m, False, reason)]

    def _first_verdict(self, time_s: float, position_m, verdicts: Verdicts) -> list[RallyEvent]:
        """The RALLY_END of the first verdict that holds (none: the rally goes on)."""
        for reason, holds in verdicts:
            if holds:
                return [self._end(time_s, position_m, reason == REASON_RETURNED, reason)]
        return []

    def _event(self, event_type: int, time_s: float, position_m) -> RallyEvent:
        return RallyEvent(self.ball_id, event_type, float(time_s), _xyz(position_m))

    def _end(self, time_s: float, position_m, success: bool, reason: str) -> RallyEvent:
        self._open = False
        return RallyEvent(self.ball_id, RALLY_END, float(time_s), _xyz(position_m), success, reason)
