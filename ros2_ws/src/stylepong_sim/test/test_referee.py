"""The referee's rules (docs/DESIGN.md, "Evaluation protocol"), one rally at a time and on arrays of balls."""

import numpy as np
import pytest
import torch

from stylepong_msgs.msg import RallyEvent as RallyEventMsg
from stylepong_sim import referee, world_spec

OWN = (-0.6, 0.1, world_spec.TABLE_CONTACT_HEIGHT_M)
OPPONENT = (0.8, -0.2, world_spec.TABLE_CONTACT_HEIGHT_M)
AIR = (-1.4, 0.0, 1.0)
FALLING = (0.0, 0.0, -1.0)


def test_event_codes_equal_the_message_constants():
    for code, name in referee.EVENT_NAMES.items():
        assert getattr(RallyEventMsg, name) == code
        assert getattr(referee, name) == code
    message_constants = {n for n in dir(RallyEventMsg) if n.isupper() and isinstance(getattr(RallyEventMsg, n), int)}
    assert message_constants == set(referee.EVENT_NAMES.values())


def _launched(ref: referee.Referee, ball_id: int = 1) -> list:
    return ref.launch(ball_id, 0.0, (1.2, 0.0, 1.0))


def _types(events) -> list[int]:
    return [e.type for e in events]


def _verdict(events) -> tuple[bool, str]:
    ends = [e for e in events if e.type == referee.RALLY_END]
    assert len(ends) == 1 and events[-1].type == referee.RALLY_END
    return ends[0].success, ends[0].reason


def test_a_return_to_the_opponents_half_succeeds():
    ref = referee.Referee()
    events = (
        _launched(ref) + ref.table_contact(0.5, OWN) + ref.paddle_contact(0.8, AIR) + ref.table_contact(1.3, OPPONENT)
    )
    assert _types(events) == [
        referee.LAUNCHED,
        referee.BOUNCE_OWN_SIDE,
        referee.PADDLE_HIT,
        referee.BOUNCE_OPPONENT_SIDE,
        referee.RALLY_END,
    ]
    assert _verdict(events) == (True, 'returned')
    assert not ref.rally_open


# A contact as the cell reports it: (the referee's method, time s, ball position).
TABLE, NET, PADDLE = referee.Referee.table_contact, referee.Referee.net_contact, referee.Referee.paddle_contact


@pytest.mark.parametrize(
    'contacts, verdict',
    [
        pytest.param(
            [(TABLE, 0.5, OWN), (PADDLE, 0.8, AIR), (NET, 1.0, AIR)],
            (False, 'net'),
            id='a_net_touching_return_fails_even_if_it_would_drop_over',
        ),
        pytest.param(
            [(TABLE, 0.5, OWN), (TABLE, 0.9, OWN)],
            (False, 'second_bounce_own_side'),
            id='a_second_bounce_on_own_side_before_a_hit_fails',
        ),
        pytest.param(
            [(PADDLE, 0.4, AIR), (TABLE, 0.9, OPPONENT)],
            (True, 'returned'),
            id='a_volley_is_judged_by_where_the_return_lands',
        ),
    ],
)
def test_the_contacts_of_a_rally_earn_its_verdict(contacts, verdict):
    ref = referee.Referee()
    events = _launched(ref)
    for report, time_s, position in contacts:
        events += report(ref, time_s, position)
    assert _verdict(events) == verdict


@pytest.mark.parametrize(
    'second, reason',
    [
        ('own_side', 'own_side'),
        ('paddle', 'double_hit'),
        ('robot', 'robot_contact'),
        ('table_by_robot', 'table_contact_by_robot'),
    ],
)
def test_failures_after_the_hit(second, reason):
    ref = referee.Referee()
    events = _launched(ref) + ref.table_contact(0.5, OWN) + ref.paddle_contact(0.8, AIR)
    events += {
        'own_side': lambda: ref.table_contact(1.0, OWN),
        'paddle': lambda: ref.paddle_contact(0.85, AIR),
        'robot': lambda: ref.robot_contact(0.85, AIR),
        'table_by_robot': lambda: ref.robot_table_contact(0.9, (-1.3, 0.0, world_spec.TABLE_HEIGHT_M)),
    }[second]()
    assert _verdict(events) == (False, reason)


def test_no_hit_ends_when_the_ball_reaches_the_floor_not_before():
    ref = referee.Referee()
    events = _launched(ref) + ref.table_contact(0.5, OWN)
    # Below the table's top behind the robot's end and falling: still hittable before the hit.
    events += ref.ball_state(0.9, (-1.6, 0.0, 0.6), FALLING)
    assert ref.rally_open
    events += ref.ball_state(1.2, (-2.0, 0.0, world_spec.BALL_RADIUS_M), FALLING)
    assert _types(events) == [referee.LAUNCHED, referee.BOUNCE_OWN_SIDE, referee.RALLY_END]
    assert _verdict(events) == (False, 'no_hit')


def test_a_returned_ball_below_the_table_top_outside_it_and_falling_is_out():
    ref = referee.Referee()
    events = _launched(ref) + ref.table_contact(0.5, OWN) + ref.paddle_contact(0.8, AIR)
    events += ref.ball_state(1.0, (-1.5, 0.0, 0.7), (1.0, 0.0, 2.0))  # rising: may still reach the table
    assert ref.rally_open
    events += ref.ball_state(1.5, (1.6, 0.0, 0.7), (3.0, 0.0, -1.0))
    assert _types(events)[-2:] == [referee.OUT, referee.RALLY_END]
    assert _verdict(events) == (False, 'out')


def test_robot_contact_before_the_hit_fails():
    ref = referee.Referee()
    events = _launched(ref) + ref.table_contact(0.5, OWN) + ref.robot_contact(0.7, AIR)
    assert _types(events) == [referee.LAUNCHED, referee.BOUNCE_OWN_SIDE, referee.ROBOT_CONTACT, referee.RALLY_END]
    assert _verdict(events) == (False, 'robot_contact')


def test_timeout():
    ref = referee.Referee(timeout_s=3.0)
    events = _launched(ref) + ref.ball_state(2.999, AIR, FALLING)
    assert ref.rally_open
    events += ref.ball_state(3.0, AIR, FALLING)
    assert _types(events) == [referee.LAUNCHED, referee.TIMEOUT, referee.RALLY_END]
    assert _verdict(events) == (False, 'timeout')


def test_a_new_launch_aborts_the_open_rally_and_each_ball_gets_exactly_one_end():
    ref = referee.Referee()
    first = _launched(ref, 1) + ref.table_contact(0.5, OWN)
    second = ref.launch(2, 0.6, (1.2, 0.0, 1.0))
    assert [(e.ball_id, e.type, e.reason) for e in second] == [
        (1, referee.RALLY_END, 'aborted'),
        (2, referee.LAUNCHED, ''),
    ]
    assert _verdict(first + second[:1]) == (False, 'aborted')
    assert ref.abort(0.7, AIR)[0].ball_id == 2
    assert ref.abort(0.8, AIR) == []


def test_silent_after_the_verdict():
    ref = referee.Referee()
    _launched(ref)
    ref.robot_contact(0.5, AIR)
    for report in (
        ref.table_contact(0.6, OPPONENT),
        ref.paddle_contact(0.6, AIR),
        ref.net_contact(0.6, AIR),
        ref.robot_table_contact(0.6, AIR),
        ref.ball_state(9.0, (0, 0, 0), FALLING),
    ):
        assert report == []


def _verdict_masks(verdicts) -> dict:
    return {reason: holds for reason, holds in verdicts}


def test_the_rules_judge_one_ball_and_arrays_of_balls_alike():
    # The cell's Referee calls the rule functions on floats and bools, the batched world on tensors [3, N]:
    # each ball of an array must get what the same ball gets alone.
    rng = np.random.default_rng(0)
    n = 400
    position = np.stack((rng.uniform(-5.5, 5.5, n), rng.uniform(-4.5, 4.5, n), rng.uniform(-0.1, 1.5, n)))
    position[:, :40] = np.array(OWN)[:, None]  # some exactly on the table's contact plane
    vz = rng.uniform(-3.0, 3.0, n)
    hit = rng.uniform(size=n) < 0.5
    own_bounces = rng.integers(0, 3, n)
    elapsed = rng.uniform(0.0, 2.0 * world_spec.BALL_TIMEOUT_S, n)
    for array in (np.asarray, torch.as_tensor):
        p, h = array(position), array(hit)
        state = _verdict_masks(referee.ball_state_verdicts(h, p, array(vz), array(elapsed), world_spec.BALL_TIMEOUT_S))
        own_side = referee.is_own_side(p)
        table = _verdict_masks(referee.table_contact_verdicts(h, own_side, array(own_bounces)))
        bounce = referee.own_side_bounce(h, own_side)
        for i in range(n):
            alone = tuple(float(x) for x in position[:, i])
            hit_i = bool(hit[i])
            expected_state = _verdict_masks(
                referee.ball_state_verdicts(hit_i, alone, float(vz[i]), float(elapsed[i]), world_spec.BALL_TIMEOUT_S)
            )
            assert {k: bool(v[i]) for k, v in state.items()} == expected_state, i
            own_i = referee.is_own_side(alone)
            expected_table = _verdict_masks(referee.table_contact_verdicts(hit_i, own_i, int(own_bounces[i])))
            assert {k: bool(v[i]) for k, v in table.items()} == expected_table, i
            assert bool(bounce[i]) == referee.own_side_bounce(hit_i, own_i)
