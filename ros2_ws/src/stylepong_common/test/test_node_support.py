"""Parameter tables: types, bounds, lengths and choices, each refused in one line naming the parameter;
throttled warnings; run_node's exit codes and the end of its loop (finished, Ctrl-C, wind_down)."""

import math
import os
import signal

import pytest
from rclpy.node import Node

from stylepong_common.exit_codes import EXIT_CONFIG_ERROR, EXIT_INTERRUPTED
from stylepong_common.node_support import (
    Param,
    ParameterError,
    ThrottledLog,
    run_node,
    typed_value,
)


@pytest.mark.parametrize(
    'param, value, expected',
    [
        (Param('rate_hz', 60.0, '', low=1.0, high=100.0), 60, 60.0),
        (Param('count', 3, '', low=0, high=10), 4, 4),
        (Param('on', False, ''), True, True),
        (Param('backend', 'onnx', '', choices=('onnx', 'torchscript')), 'torchscript', 'torchscript'),
        (Param('goal', [0.5, 0.0], '', length=2), [1, 0.25], [1.0, 0.25]),
        (Param('names', ['a'], ''), ['b', 'c'], ['b', 'c']),
    ],
)
def test_good_values_come_back_in_the_default_type(param, value, expected):
    got = typed_value(param, value)
    assert got == expected and type(got) is type(expected)


@pytest.mark.parametrize(
    'param, value, words',
    [
        (Param('rate_hz', 60.0, '', low=1.0, high=100.0), 'fast', 'a number'),
        (Param('rate_hz', 60.0, '', low=1.0, high=100.0), 500.0, 'within'),
        (Param('rate_hz', 60.0, ''), math.nan, 'finite'),
        (Param('rate_hz', 60.0, ''), True, 'a number'),
        (Param('count', 3, ''), 2.5, 'an integer'),
        (Param('on', False, ''), 1, 'true or false'),
        (Param('backend', 'onnx', '', choices=('onnx', 'torchscript')), 'tensorrt', 'one of'),
        (Param('goal', [0.5, 0.0], '', length=2), [1.0], '2 elements'),
        (Param('goal', [0.5, 0.0], '', length=2, high=1.0), [1.0, 2.0], 'at most 1.0'),
        (Param('goal', [0.5, 0.0], '', low=-1.0, high=1.0), [1.0, 2.0], 'within [-1.0, 1.0]'),
        (Param('goal', [0.5, 0.0], ''), ['x', 1.0], 'numbers'),
        (Param('seed', 0, '', low=0), -1, 'at least 0'),
        (Param('gain', 1.0, '', high=2.0), 3.0, 'at most 2.0'),
    ],
)
def test_bad_values_are_refused_in_one_line_naming_the_parameter(param, value, words):
    with pytest.raises(ParameterError) as error:
        typed_value(param, value)
    text = str(error.value)
    assert param.name in text and words in text and '\n' not in text


def test_throttled_log_holds_back_floods_and_says_how_many():
    lines = []

    class Logger:
        def warning(self, text):
            lines.append(text)

    now = [0.0]
    log = ThrottledLog(Logger(), period_s=1.0, clock=lambda: now[0])
    built = []
    for k in range(100):
        now[0] = k * 0.01
        log.warn('ball', lambda: built.append(1) or 'bad ball')
    now[0] = 1.5
    log.warn('ball', 'bad ball')
    log.warn('joints', 'bad joints')
    assert lines == ['bad ball', 'bad ball (99 more since the last such message)', 'bad joints']
    assert len(built) == 1  # the text of held-back messages is never built


def test_a_one_sided_bound_is_said_without_the_missing_side():
    with pytest.raises(ParameterError) as error:
        typed_value(Param('seed', 0, '', low=0), -1)
    assert 'None' not in str(error.value) and 'inf' not in str(error.value)


class _ScriptedNode(Node):
    """Ends its loop by itself (finished) or by sending itself SIGINT; records what run_node calls."""

    def __init__(self, calls: list, interrupt: bool):
        super().__init__('scripted')
        self.calls = calls
        self.finished = False
        self._interrupt = interrupt
        self.create_timer(0.01, self._on_timer)

    def _on_timer(self) -> None:
        if self._interrupt:
            os.kill(os.getpid(), signal.SIGINT)
        else:
            self.finished = True

    def wind_down(self, executor, interrupted: bool) -> None:
        executor.spin_once(timeout_sec=0.01)  # the executor still serves the node here
        self.calls.append(('wind_down', interrupted))
        self.exit_code = 130 if interrupted else 7

    def close(self) -> None:
        self.calls.append(('close',))


@pytest.fixture
def own_signal_handlers():
    """run_node installs SIGINT/SIGTERM handlers for a whole program: give pytest its own back."""
    saved = {signum: signal.getsignal(signum) for signum in (signal.SIGINT, signal.SIGTERM)}
    yield
    for signum, handler in saved.items():
        signal.signal(signum, handler)


@pytest.mark.parametrize('interrupt, code', [(False, 7), (True, EXIT_INTERRUPTED)])
def test_run_node_winds_down_before_closing_and_returns_the_nodes_exit_code(own_signal_handlers, interrupt, code):
    calls = []
    assert run_node('scripted', lambda: _ScriptedNode(calls, interrupt), args=['scripted']) == code
    assert calls == [('wind_down', interrupt), ('close',)]


def test_run_node_turns_a_bad_parameter_into_one_line_and_exit_code_2(own_signal_handlers, capfd):
    def bad_node():
        raise ParameterError('parameter rate_hz must be within [1.0, 100.0],\n got 500.0')

    assert run_node('prog', bad_node, args=['prog']) == EXIT_CONFIG_ERROR
    assert capfd.readouterr().err == 'prog: parameter rate_hz must be within [1.0, 100.0], got 500.0\n'
