"""What StylePong's nodes share: parameters from one table, throttled warnings, and the executor loop.

    PARAMETERS = (Param('rate_hz', 60.0, 'loop rate', low=1.0, high=1000.0), ...)
    values = declare_parameters(node, PARAMETERS)      # dict name -> value in the default's type
    warnings = ThrottledLog(node.get_logger())       # at most one line per kind every WARN_PERIOD_S
    warnings.warn('joint_state', lambda: f'rejected: {reason}')
    sys.exit(run_node('player', PlayerNode, config_errors=(ActorMismatchError,)))

Parameters are declared with dynamic typing, so that `-p rate_hz:=60` (an integer) works for a float
parameter, and then converted and checked here: a wrong type, a value outside its range, a list of the
wrong length or a name not among its choices raises ParameterError with one line that names the parameter.
`run_node` turns that (and any error class the node adds) into that line on stderr and exit code 2, so a
mistyped launch file fails loudly at start instead of running a robot with a half-understood setting.
"""

from __future__ import annotations

import math
import signal
import sys
import time
from dataclasses import dataclass
from typing import Any, Callable, Iterable, Union

import rclpy
from rcl_interfaces.msg import ParameterDescriptor
from rclpy._rclpy_pybind11 import RCLError
from rclpy.exceptions import InvalidParameterTypeException, InvalidParameterValueException
from rclpy.executors import Executor, ExternalShutdownException
from rclpy.experimental import EventsExecutor
from rclpy.node import Node
from rclpy.signals import SignalHandlerOptions

from stylepong_common.exit_codes import EXIT_CONFIG_ERROR

ParameterValue = Union[bool, int, float, str, list]
# How often a node repeats a warning of one kind (ThrottledLog's default): a flood of bad messages at
# 500 Hz shows as one line every two seconds with the count held back, readable and still current.
WARN_PERIOD_S = 2.0


class ParameterError(ValueError):
    """A parameter has the wrong type or value; the message is one line naming it."""


@dataclass(frozen=True)
class Param:
    """One row of a node's parameter table: the default's type is the parameter's type.

    low/high bound numbers (and every element of a numeric list); length fixes a list's length;
    choices lists the strings a str parameter may take.
    """

    name: str
    default: ParameterValue
    description: str
    low: float | None = None
    high: float | None = None
    length: int | None = None
    choices: tuple[str, ...] = ()
    read_only: bool = True

    def describe(self) -> str:
        text = self.description
        if self.low is not None or self.high is not None:
            text += (
                f' [{self.low if self.low is not None else "-inf"}, {self.high if self.high is not None else "inf"}]'
            )
        if self.choices:
            text += f' (one of {", ".join(self.choices)})'
        return text


def _is_number(value: Any) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool)


def typed_value(param: Param, value: Any) -> ParameterValue:
    """`value` in the type of `param.default`, checked against the row's bounds; ParameterError otherwise."""
    default = param.default
    kind = type(default).__name__

    def bad(why: str) -> ParameterError:
        return ParameterError(f'parameter {param.name} {why}, got {value!r}')

    if isinstance(default, bool):
        if not isinstance(value, bool):
            raise bad('must be true or false')
        return value
    if isinstance(default, (int, float)):
        if not _is_number(value) or (isinstance(default, int) and not isinstance(value, int)):
            raise bad(f'must be {"an integer" if isinstance(default, int) else "a number"}')
        number = type(default)(value)
        _check_bounds(param, [float(number)], bad)
        return number
    if isinstance(default, str):
        if not isinstance(value, str):
            raise bad('must be a string')
        if param.choices and value not in param.choices:
            raise bad(f'must be one of {", ".join(param.choices)}')
        return value
    if isinstance(default, list):
        if isinstance(value, (str, bytes)) or not hasattr(value, '__len__'):
            raise bad('must be a list')
        items = list(value)
        if param.length is not None and len(items) != param.length:
            raise bad(f'must have {param.length} elements')
        strings = isinstance(default[0], str) if default else bool(items) and isinstance(items[0], str)
        if strings:
            if not all(isinstance(v, str) for v in items):
                raise bad('must be a list of strings')
            return items
        if not all(_is_number(v) for v in items):
            raise bad('must be a list of numbers')
        numbers = [float(v) for v in items]
        _check_bounds(param, numbers, bad)
        return numbers
    raise TypeError(f'parameter {param.name}: unsupported default type {kind}')


def _check_bounds(param: Param, numbers: list[float], bad: Callable[[str], ParameterError]) -> None:
    low = -math.inf if param.low is None else param.low
    high = math.inf if param.high is None else param.high
    for number in numbers:
        if not math.isfinite(number):
            raise bad('must be finite')
        if not low <= number <= high:
            raise bad(_bounds_text(param))


def _bounds_text(param: Param) -> str:
    """What a value outside the row's bounds must be, in words (a one-sided bound has no `None` in it)."""
    if param.high is None:
        return f'must be at least {param.low}'
    if param.low is None:
        return f'must be at most {param.high}'
    return f'must be within [{param.low}, {param.high}]'


def declare_parameters(node: Node, table: Iterable[Param]) -> dict[str, ParameterValue]:
    """Declare every row on `node` (descriptions and bounds visible to `ros2 param describe`) and return
    the checked values, name -> value. Raises ParameterError on the first bad one."""
    rows = list(table)
    for row in rows:
        descriptor = ParameterDescriptor(description=row.describe(), read_only=row.read_only, dynamic_typing=True)
        node.declare_parameter(row.name, row.default, descriptor)
    return {row.name: typed_value(row, node.get_parameter(row.name).value) for row in rows}


class ThrottledLog:
    """Warnings (or infos) throttled per key: at most one per period_s, saying how many were held back.

    `text` may be a callable, so that under a flood of bad messages the text is built only when logged.
    Times are monotonic wall time: a flood is a flood whatever clock the node runs on.
    """

    def __init__(self, logger, period_s: float = WARN_PERIOD_S, clock: Callable[[], float] = time.monotonic):
        self._logger = logger
        self._period_s = period_s
        self._clock = clock
        self._last_s: dict[str, float] = {}
        self._held_back: dict[str, int] = {}

    # rclpy ties a severity to the line that calls the logger and raises if one line logs at two
    # severities: each severity has its own call below.
    def warn(self, key: str, text: str | Callable[[], str]) -> bool:
        message = self._due(key, text)
        if message is not None:
            self._logger.warning(message)
        return message is not None

    def info(self, key: str, text: str | Callable[[], str]) -> bool:
        message = self._due(key, text)
        if message is not None:
            self._logger.info(message)
        return message is not None

    def _due(self, key: str, text: str | Callable[[], str]) -> str | None:
        """The message to log now for `key`, or None while its period has not passed."""
        now = self._clock()
        if now - self._last_s.get(key, -math.inf) < self._period_s:
            self._held_back[key] = self._held_back.get(key, 0) + 1
            return None
        self._last_s[key] = now
        message = text() if callable(text) else text
        held_back = self._held_back.pop(key, 0)
        if held_back:
            message += f' ({held_back} more since the last such message)'
        return message


def one_line(error: BaseException) -> str:
    """An exception's message on one line (its type's name when the message is empty)."""
    return ' '.join(str(error).split()) or type(error).__name__


def run_node(
    program: str,
    make_node: Callable[[], Node],
    args: list[str] | None = None,
    config_errors: tuple[type[BaseException], ...] = (),
    make_executor: Callable[[], Executor] = EventsExecutor,
) -> int:
    """Build the node and spin it until Ctrl-C or SIGTERM; returns the process exit code.

    A ParameterError, rclpy's parameter exceptions or any of `config_errors` raised while building the
    node print `<program>: <reason>` (one line) on stderr and return EXIT_CONFIG_ERROR. The node's
    `close()`, if it has one, runs on the way out (statistics, files); a node that sets `finished` ends the
    loop, with its `exit_code` (default 0). A node with `wind_down(executor, interrupted)` gets that call
    when the loop ends (interrupted: by Ctrl-C or SIGTERM), while the executor still serves it: the last
    messages and service answers it needs to leave things tidy (let go of the paddle, close a clip), and
    the exit code it then sets.

    `make_executor` builds the executor (the events executor unless a node needs another: rclpy 7.1's
    events executor fails on subscription callbacks that take the message info, which the recorder reads
    its receive times from).
    """
    # Ctrl-C and SIGTERM only ask the loop below to stop: rclpy's own handler would raise inside a
    # callback half-way through it.
    rclpy.init(args=args, signal_handler_options=SignalHandlerOptions.NO)
    stop_requested: list[int] = []
    for signum in (signal.SIGINT, signal.SIGTERM):
        signal.signal(signum, lambda received, _frame: stop_requested.append(received))
    node = None
    # The C++ events executor costs a fraction of the Python one per wake-up. Its spin() never returns
    # to Python (no Ctrl-C), hence spin_once in a loop.
    executor = make_executor()
    errors = (ParameterError, InvalidParameterValueException, InvalidParameterTypeException, *config_errors)
    try:
        node = make_node()
        executor.add_node(node)
        # A node that ends by itself (a replay) sets `finished` and, optionally, `exit_code`.
        while rclpy.ok() and not stop_requested and not getattr(node, 'finished', False):
            executor.spin_once(timeout_sec=0.1)
        wind_down = getattr(node, 'wind_down', None)
        if wind_down is not None:
            wind_down(executor, bool(stop_requested))
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    except errors as error:
        print(f'{program}: {one_line(error)}', file=sys.stderr)
        return EXIT_CONFIG_ERROR
    except RCLError:
        if rclpy.ok():
            raise
        # Stopped while the node was still being built: nothing else to clean up.
    finally:
        # The executor lets go of the node's handles first: destroying them while it holds them can hang.
        executor.shutdown()
        if node is not None:
            close = getattr(node, 'close', None)
            if close is not None:
                close()
            node.destroy_node()
        rclpy.try_shutdown()
    return int(getattr(node, 'exit_code', 0) or 0)
