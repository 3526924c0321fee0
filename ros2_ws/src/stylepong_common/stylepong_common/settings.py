"""Settings dataclasses whose numbers state their range where they are declared (no rclpy).

    @dataclass(frozen=True)
    class ClipOptions:
        max_gap_s: float = positive(0.1)
        min_frames: int = at_least(2, 2)

        def validate(self) -> None:
            check_ranges(self)      # ValueError naming the first setting out of its range

A field made by positive, non_negative, at_least or within must hold a finite number in that range.
check_ranges reads the ranges back from the fields, so a setting is checked by being declared, and its
rule stands beside its default instead of in a list elsewhere that a new setting could miss.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any

_RANGE_KEY = 'stylepong_common.settings.range'


@dataclasses.dataclass(frozen=True)
class Range:
    """The values a setting may take: finite numbers from low to high, low itself only if low_included."""

    low: float
    low_included: bool
    high: float = math.inf
    text: str = ''  # what check_ranges says the setting must be

    def admits(self, value: Any) -> bool:
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
            return False  # a YAML typo ('1e-4' is a string to YAML 1.1) is refused here, not deep in training
        above_low = value > self.low or (self.low_included and value == self.low)
        return above_low and value <= self.high


def positive(default: float) -> Any:
    """A dataclass field whose value must be a finite number above 0."""
    return _field(default, Range(0.0, False, text='must be positive'))


def non_negative(default: float) -> Any:
    """A dataclass field whose value must be a finite number, 0 or more."""
    return _field(default, Range(0.0, True, text='must not be negative'))


def at_least(default: float, low: float) -> Any:
    """A dataclass field whose value must be a finite number, `low` or more."""
    return _field(default, Range(low, True, text=f'must be at least {low}'))


def within(default: float, low: float, high: float) -> Any:
    """A dataclass field whose value must be a finite number from `low` to `high`, both included."""
    return _field(default, Range(low, True, high, text=f'must be in [{low}, {high}]'))


def check_ranges(settings: Any, prefix: str = '') -> None:
    """ValueError '<prefix><name> must be ..., got <value>' for the first field of the dataclass instance
    `settings`, in declaration order, whose value its range does not admit."""
    for field in dataclasses.fields(settings):
        bound = declared_range(field)
        value = getattr(settings, field.name)
        if bound is not None and not bound.admits(value):
            raise ValueError(f'{prefix}{field.name} {bound.text}, got {value!r}')


def declared_range(field: dataclasses.Field) -> Range | None:
    """The range a field made by positive, non_negative, at_least or within declares; None for another field."""
    return field.metadata.get(_RANGE_KEY)


def _field(default: float, bound: Range) -> Any:
    # Typed Any as dataclasses.field is to type checkers: the field's value, not a Field object.
    return dataclasses.field(default=default, metadata={_RANGE_KEY: bound})
