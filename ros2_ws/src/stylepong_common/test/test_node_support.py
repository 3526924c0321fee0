"""Parameter tables: types, bounds, lengths and choices, each refused in one line naming the parameter."""
import math

import pytest

from stylepong_common.node_support import Param, ParameterError, ThrottledLog, typed_value


@pytest.mark.parametrize('param, value, expected', [
    (Param('rate_hz', 60.0, '', low=1.0, high=100.0), 60, 60.0),
    (Param('count', 3, '', low=0, high=10), 4, 4),
    (Param('on', False, ''), True, True),
    (Param('backend', 'onnx', '', choices=('onnx', 'torchscript')), 'torchscript', 'torchscript'),
    (Param('goal', [0.5, 0.0], '', length=2), [1, 0.25], [1.0, 0.25]),
    (Param('names', ['a'], ''), ['b', 'c'], ['b', 'c']),
])
def test_good_values_come_back_in_the_default_type(param, value, expected):
    got = typed_value(param, value)
    assert got == expected and type(got) is type(expected)


@pytest.mark.parametrize('param, value, words', [
    (Param('rate_hz', 60.0, '', low=1.0, high=100.0), 'fast', 'a number'),
    (Param('rate_hz', 60.0, '', low=1.0, high=100.0), 500.0, 'within'),
    (Param('rate_hz', 60.0, ''), math.nan, 'finite'),
    (Param('rate_hz', 60.0, ''), True, 'a number'),
    (Param('count', 3, ''), 2.5, 'an integer'),
    (Param('on', False, ''), 1, 'true or false'),
    (Param('backend', 'onnx', '', choices=('onnx', 'torchscript')), 'tensorrt', 'one of'),
    (Param('goal', [0.5, 0.0], '', length=2), [1.0], '2 elements'),
    (Param('goal', [0.5, 0.0], '', length=2, high=1.0), [1.0, 2.0], 'within'),
    (Param('goal', [0.5, 0.0], ''), ['x', 1.0], 'numbers'),
])
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
    assert len(built) == 1   # the text of held-back messages is never built
