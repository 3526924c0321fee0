"""The rally referee: the evaluation protocol (docs/DESIGN.md, "Evaluation protocol") as a small
state machine, free of ROS.

A simulator reports what happens to the ball it launched (contacts, its state every physics step);
the referee turns that into the ball's RallyEvent sequence. The batched training world implements
the same rules in torch, so here they are in full.

Events (codes identical to stylepong_msgs/RallyEvent):
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

from stylepong_sim import world_spec as ws

# Mirror of stylepong_msgs/RallyEvent's constants (a unit test keeps them equal).
LAUNCHED = 0
BOUNCE_OWN_SIDE = 1
PADDLE_HIT = 2
BOUNCE_OPPONENT_SIDE = 3
NET = 4
ROBOT_CONTACT = 5
TABLE_CONTACT_BY_ROBOT = 6
OUT = 7
TIMEOUT = 8
RALLY_END = 9

EVENT_NAMES = {
    LAUNCHED: 'LAUNCHED', BOUNCE_OWN_SIDE: 'BOUNCE_OWN_SIDE', PADDLE_HIT: 'PADDLE_HIT',
    BOUNCE_OPPONENT_SIDE: 'BOUNCE_OPPONENT_SIDE', NET: 'NET', ROBOT_CONTACT: 'ROBOT_CONTACT',
    TABLE_CONTACT_BY_ROBOT: 'TABLE_CONTACT_BY_ROBOT', OUT: 'OUT', TIMEOUT: 'TIMEOUT', RALLY_END: 'RALLY_END',
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


def ball_is_dead(position_m) -> bool:
    """The ball's bottom touched the floor or its centre left the cell."""
    x, y, z = _xyz(position_m)
    return z <= ws.BALL_RADIUS_M or abs(x) > ws.CELL_HALF_EXTENT_M[0] or abs(y) > ws.CELL_HALF_EXTENT_M[1]


def ball_cannot_reach_table(position_m, vertical_velocity_m_s: float) -> bool:
    """Bottom below the table top, outside the footprint, falling: the table top is out of reach."""
    x, y, z = _xyz(position_m)
    return (z - ws.BALL_RADIUS_M < ws.TABLE_HEIGHT_M and not ws.on_table(x, y)
            and vertical_velocity_m_s < 0.0)


class Referee:
    """Judges one ball at a time. Every method returns the events it produced (possibly none)."""

    def __init__(self, timeout_s: float = ws.BALL_TIMEOUT_S):
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
        own_side = float(position_m[0]) < 0.0
        event = self._event(BOUNCE_OWN_SIDE if own_side else BOUNCE_OPPONENT_SIDE, time_s, position_m)
        if self._hit:
            if own_side:
                return [event, self._end(time_s, position_m, False, REASON_OWN_SIDE)]
            return [event, self._end(time_s, position_m, True, REASON_RETURNED)]
        if own_side:
            self._own_bounces += 1
            if self._own_bounces >= 2:
                return [event, self._end(time_s, position_m, False, REASON_SECOND_BOUNCE_OWN_SIDE)]
        return [event]

    def net_contact(self, time_s: float, position_m) -> list[RallyEvent]:
        if not self._open:
            return []
        event = self._event(NET, time_s, position_m)
        if self._hit:
            return [event, self._end(time_s, position_m, False, REASON_NET)]
        return [event]

    def paddle_contact(self, time_s: float, position_m) -> list[RallyEvent]:
        if not self._open:
            return []
        event = self._event(PADDLE_HIT, time_s, position_m)
        if self._hit:
            return [event, self._end(time_s, position_m, False, REASON_DOUBLE_HIT)]
        self._hit = True
        return [event]

    def robot_contact(self, time_s: float, position_m) -> list[RallyEvent]:
        if not self._open:
            return []
        return [self._event(ROBOT_CONTACT, time_s, position_m),
                self._end(time_s, position_m, False, REASON_ROBOT_CONTACT)]

    def robot_table_contact(self, time_s: float, contact_point_m) -> list[RallyEvent]:
        if not self._open:
            return []
        return [self._event(TABLE_CONTACT_BY_ROBOT, time_s, contact_point_m),
                self._end(time_s, contact_point_m, False, REASON_TABLE_CONTACT_BY_ROBOT)]

    def ball_state(self, time_s: float, position_m, velocity_m_s) -> list[RallyEvent]:
        """Called with the ball's state after every physics step: timeout, dead and out balls."""
        if not self._open:
            return []
        dead = ball_is_dead(position_m)
        if dead and not self._hit:
            return [self._end(time_s, position_m, False, REASON_NO_HIT)]
        if self._hit and (dead or ball_cannot_reach_table(position_m, float(velocity_m_s[2]))):
            return [self._event(OUT, time_s, position_m), self._end(time_s, position_m, False, REASON_OUT)]
        if time_s - self._launch_time_s >= self.timeout_s:
            return [self._event(TIMEOUT, time_s, position_m), self._end(time_s, position_m, False, REASON_TIMEOUT)]
        return []

    def _event(self, event_type: int, time_s: float, position_m) -> RallyEvent:
        return RallyEvent(self.ball_id, event_type, float(time_s), _xyz(position_m))

    def _end(self, time_s: float, position_m, success: bool, reason: str) -> RallyEvent:
        self._open = False
        return RallyEvent(self.ball_id, RALLY_END, float(time_s), _xyz(position_m), success, reason)
