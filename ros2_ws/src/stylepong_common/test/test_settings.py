"""settings: ranges declared with the fields, checked in declaration order, refused in one line naming them."""

import math
from dataclasses import dataclass

import pytest

from stylepong_common.settings import at_least, check_ranges, non_negative, positive, within


@dataclass
class Example:
    rate_hz: float = positive(60.0)
    weight: float = non_negative(0.0)
    frames: int = at_least(2, 2)
    gamma: float = within(0.99, 0.0, 1.0)
    name: str = 'free'  # no range: never checked


def test_the_defaults_pass():
    check_ranges(Example())


@pytest.mark.parametrize(
    'changes, message',
    [
        ({'rate_hz': 0.0}, 'rate_hz must be positive, got 0.0'),
        ({'weight': -0.1}, 'weight must not be negative, got -0.1'),
        ({'frames': 1}, 'frames must be at least 2, got 1'),
        ({'gamma': 1.5}, 'gamma must be in [0.0, 1.0], got 1.5'),
        ({'rate_hz': math.nan}, 'rate_hz must be positive, got nan'),
        ({'rate_hz': math.inf}, 'rate_hz must be positive, got inf'),
        ({'rate_hz': '60'}, "rate_hz must be positive, got '60'"),
        ({'rate_hz': True}, 'rate_hz must be positive, got True'),
    ],
)
def test_a_value_out_of_its_range_is_refused_naming_it(changes, message):
    with pytest.raises(ValueError) as error:
        check_ranges(Example(**changes))
    assert str(error.value) == message


def test_the_bounds_themselves_are_admitted_where_included():
    check_ranges(Example(rate_hz=1e-9, weight=0.0, frames=2, gamma=1.0))
    check_ranges(Example(gamma=0.0))


def test_the_first_field_out_of_range_is_named_with_the_prefix():
    with pytest.raises(ValueError, match=r'^amp\.rate_hz '):
        check_ranges(Example(rate_hz=-1.0, weight=-1.0), prefix='amp.')
