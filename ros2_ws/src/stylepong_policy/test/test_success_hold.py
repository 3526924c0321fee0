"""rl.success_hold: the motion terms' scale falls while training success is below the skill's own less the
margin, climbs back as it recovers, weighs iterations by their episodes, and a resumed run continues
where it was, and at the recipe's gain it settles on a policy whose success answers the scale late."""

import math

import pytest

from stylepong_policy.rl.config import load_config
from stylepong_policy.rl.success_hold import SuccessHold
from stylepong_policy.training.train import default_config_path


def _hold(smoothing: float = 0.5) -> SuccessHold:
    return SuccessHold(warmup_iterations=3, margin=0.05, gain=0.5, smoothing=smoothing)


def _warm(hold: SuccessHold, rate: float = 0.9) -> None:
    for _ in range(3):
        hold.observe(rate, 100)


def test_the_warm_up_sets_the_floor_from_its_episodes_and_leaves_the_scale_alone():
    hold = _hold()
    # A run's first iterations end few episodes at wild rates: weighed by episodes they barely count.
    assert [hold.observe(r, n) for r, n in ((0.0, 10), (0.9, 500), (0.8, 490))] == [1.0, 1.0, 1.0]
    assert hold.floor == pytest.approx((0.9 * 500 + 0.8 * 490) / 1000 - 0.05)


def test_returns_below_the_floor_lower_the_scale_to_zero_and_recovered_returns_restore_it():
    hold = _hold()
    _warm(hold)
    scales = [hold.observe(0.5, 100) for _ in range(20)]
    assert all(b < a for a, b in zip(scales, scales[1:]) if a > 0.0) and scales[-1] == 0.0
    scales = [hold.observe(0.95, 100) for _ in range(40)]
    # It stays down until the smoothed success is back over the floor, then rises to the recipe's own weights.
    assert scales == sorted(scales) and scales[0] == 0.0 and scales[-1] == 1.0


def test_returns_at_the_floor_keep_the_scale():
    hold = _hold()
    _warm(hold)
    hold.observe(0.2, 100)
    held, floor = hold.scale, hold.floor
    # With full smoothing s is the iteration's own rate: at the floor the step is nil.
    hold.smoothing = 1.0
    assert hold.observe(floor, 100) == pytest.approx(held)


def test_an_iteration_without_ended_episodes_changes_nothing():
    hold = _hold()
    for rate, episodes in ((0.9, 100), (None, 0), (math.nan, 50), (0.5, 0), (0.9, 100), (0.9, 100)):
        hold.observe(rate, episodes)
    assert hold.floor == pytest.approx(0.85)
    before = hold.state_dict()
    assert hold.observe(None, None) == 1.0 and hold.state_dict() == before


def test_a_resumed_hold_continues_as_the_first_would_have():
    first, resumed = _hold(smoothing=0.1), _hold(smoothing=0.1)
    for rate in (0.9, 0.8, 0.85, 0.6, 0.7):
        first.observe(rate, 120)
    resumed.load_state_dict(first.state_dict())
    rates = (0.5, 0.9, 0.95)
    assert [resumed.observe(r, 80) for r in rates] == [first.observe(r, 80) for r in rates]


def _late_policy_scales(gain: float, delay_iterations: int) -> list[float]:
    """The hold against a policy like the learn_style runs': after the 10 warm-up iterations (the actor still
    the skill), training success 0.905 less 0.09 x the scale it was given delay_iterations before, reached
    with a 10-iteration lag; 300 episodes an iteration."""
    hold = SuccessHold(warmup_iterations=10, margin=0.03, gain=gain, smoothing=0.1)
    given, success, scales = [1.0] * delay_iterations, 0.905, []
    for iteration in range(1500):
        if iteration >= 10:
            success += (0.905 - 0.09 * given[-delay_iterations] - success) / 10.0
        scales.append(hold.observe(success, 300))
        given.append(scales[-1])
    return scales[500:]


@pytest.mark.parametrize('delay_iterations', [20, 30, 40])
def test_at_the_recipes_gain_a_late_answering_policy_settles_where_the_gain_of_half_swung(delay_iterations):
    gain = load_config(default_config_path('amp')).amp.hold_success_gain
    settled = _late_policy_scales(gain, delay_iterations)
    # Equilibrium: 0.905 - 0.09 scale = the floor 0.875, scale 1/3.
    assert max(settled) - min(settled) < 0.05 and sum(settled) / len(settled) == pytest.approx(1 / 3, abs=0.01)
    if delay_iterations >= 30:
        swung = _late_policy_scales(0.5, delay_iterations)
        assert min(swung) == 0.0 and max(swung) > 0.75
