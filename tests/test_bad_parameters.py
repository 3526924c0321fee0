"""Every node refuses a bad parameter the same way, started as a person would (`ros2 run`); rally_eval a bad flag.

The shared convention (stylepong_common.node_support): exit code 2, one line on stderr, `<program>: <reason>`
naming the parameter, and at once: the node stops while it is being built instead of spinning with a
half-understood setting. The package unit tests check each node's table value by value; this checks the
installed executables end to end, the recorder under its old package name too.
"""

from __future__ import annotations

import subprocess

import pytest

from stylepong_common.exit_codes import EXIT_CONFIG_ERROR

# Start-up of a refused node is a Python start and its imports (about 2 s on a 2-core machine beside a
# training run); a node that does not stop would run until killed.
PROMPT_EXIT_S = 30.0

CASES = [
    pytest.param(
        'stylepong_fdcc', 'drag_teach', ('--ros-args', '-p', 'control_rate_hz:=5.0'), 'control_rate_hz', id='drag_teach'
    ),
    pytest.param(
        'stylepong_sim', 'ur5_sim', ('--ros-args', '-p', 'ball_latency_s:=-0.5'), 'ball_latency_s', id='ur5_sim'
    ),
    pytest.param(
        'stylepong_sim', 'virtual_teacher', ('--ros-args', '-p', 'swing:=sideways'), 'swing', id='virtual_teacher'
    ),
    pytest.param(
        'stylepong_player', 'player', ('--ros-args', '-p', 'status_rate_hz:=0.0'), 'status_rate_hz', id='player'
    ),
    pytest.param('stylepong_sim', 'rally_eval', ('--speed', 'fast'), '--speed', id='rally_eval'),
    pytest.param(
        'stylepong_recording', 'recorder', ('--ros-args', '-p', 'flush_period_s:=-0.1'), 'flush_period_s', id='recorder'
    ),
    pytest.param(
        'stylepong_fdcc',
        'recorder',
        ('--ros-args', '-p', 'flush_period_s:=-0.1'),
        'flush_period_s',
        id='recorder-compatibility-name',
    ),
]


@pytest.mark.parametrize('package, executable, args, name', CASES)
def test_a_bad_parameter_stops_the_program_at_once_with_one_line_and_exit_code_2(
    ros_env, package, executable, args, name
):
    try:
        result = subprocess.run(
            ['ros2', 'run', package, executable, *args],
            capture_output=True,
            text=True,
            env=ros_env,
            timeout=PROMPT_EXIT_S,
        )
    except subprocess.TimeoutExpired as expired:
        pytest.fail(f'{executable} still running {PROMPT_EXIT_S:.0f} s after a bad {name}: {expired.stderr!r}')
    lines = result.stderr.strip().splitlines()
    assert result.returncode == EXIT_CONFIG_ERROR, (result.returncode, result.stderr)
    assert len(lines) == 1 and lines[0].startswith(f'{executable}: ') and name in lines[0], result.stderr
