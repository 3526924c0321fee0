"""The workspace after `source ros2_ws/install/setup.bash`: interfaces, index, `ros2` command."""

import contextlib
import os
import pathlib
import re
import select
import signal
import stat
import subprocess
import sys
import threading
import time

import pytest

from tests.test_one_home import EVENT_CODES  # the rally events RallyEvent.msg defines

PACKAGES = (
    'stylepong_msgs',
    'stylepong_description',
    'stylepong_sim',
    'stylepong_fdcc',
    'stylepong_recording',
    'stylepong_player',
    'stylepong_policy',
    'stylepong_ros2cli',
)


def test_python3_is_the_project_interpreter_with_rclpy():
    out = subprocess.run(
        ['python3', '-c', 'import rclpy, sys; print(sys.prefix)'], capture_output=True, text=True, check=True
    ).stdout.strip()
    assert pathlib.Path(out).resolve() == pathlib.Path(sys.prefix).resolve()


def test_interfaces_have_the_documented_fields_and_constants():
    from stylepong_msgs.msg import BallState, RallyEvent
    from stylepong_msgs.srv import LaunchBall, StartClip

    assert list(BallState.get_fields_and_field_types()) == [
        'header',
        'position',
        'velocity',
        'position_covariance',
        'velocity_covariance',
    ]
    assert BallState.get_fields_and_field_types()['position'] == 'geometry_msgs/Point'
    assert BallState.get_fields_and_field_types()['velocity_covariance'] == 'double[9]'
    assert list(RallyEvent.get_fields_and_field_types()) == [
        'header',
        'ball_id',
        'type',
        'position',
        'success',
        'reason',
    ]
    values = [getattr(RallyEvent, n) for n in EVENT_CODES]
    assert len(set(values)) == len(EVENT_CODES)
    assert list(LaunchBall.Request.get_fields_and_field_types()) == [
        'position',
        'velocity',
        'randomize',
        'speed_min',
        'speed_max',
        'seed',
    ]
    assert LaunchBall.Request.get_fields_and_field_types()['seed'] == 'uint32'
    assert list(LaunchBall.Response.get_fields_and_field_types()) == [
        'ball_id',
        'position',
        'velocity',
        'success',
        'message',
    ]
    assert list(StartClip.Request.get_fields_and_field_types()) == ['label']
    assert list(StartClip.Response.get_fields_and_field_types()) == ['success', 'bag_path', 'message']


def test_all_packages_are_indexed():
    from ament_index_python.packages import get_package_share_directory

    for package in PACKAGES:
        assert pathlib.Path(get_package_share_directory(package), 'package.xml').is_file()


def test_unknown_package_is_reported_like_ros2run():
    result = subprocess.run(['ros2', 'run', 'no_such_pkg', 'x'], capture_output=True, text=True)
    assert result.returncode != 0
    assert "Package 'no_such_pkg' not found" in result.stderr


def test_unknown_executable_is_reported():
    result = subprocess.run(['ros2', 'run', 'stylepong_sim', 'no_such_exe'], capture_output=True, text=True)
    assert result.returncode != 0
    assert 'No executable found' in result.stderr


@pytest.fixture
def fake_package(tmp_path, monkeypatch):
    """An installed package `sp_fake` with executable `probe` that reports its pid and arguments."""
    prefix = tmp_path / 'install'
    (prefix / 'share/ament_index/resource_index/packages').mkdir(parents=True)
    (prefix / 'share/ament_index/resource_index/packages/sp_fake').write_text('')
    lib = prefix / 'lib/sp_fake'
    lib.mkdir(parents=True)
    probe = lib / 'probe'
    probe.write_text(
        '#!/bin/sh\ntrap "echo got-sigint; exit 7" INT\n'
        'echo "pid=$$ prefix=${SP_PREFIX:-none} args=$*"\nsleep 30 & wait\n'
    )
    probe.chmod(probe.stat().st_mode | stat.S_IXUSR)
    monkeypatch.setenv('AMENT_PREFIX_PATH', f'{prefix}:{os.environ["AMENT_PREFIX_PATH"]}')
    return prefix


def _read_line(process) -> str:
    return process.stdout.readline().strip()


def test_run_execs_the_node_and_passes_arguments(fake_package):
    process = subprocess.Popen(
        ['ros2', 'run', 'sp_fake', 'probe', 'a', '--ros-args', '-p', 'x:=1'], stdout=subprocess.PIPE, text=True
    )
    line = _read_line(process)
    # exec: the node is the very process that was started, so signals reach it.
    assert line == f'pid={process.pid} prefix=none args=a --ros-args -p x:=1'
    process.send_signal(signal.SIGINT)
    assert process.wait(10) == 7
    assert _read_line(process) == 'got-sigint'


def test_run_prefix_goes_in_front(fake_package):
    process = subprocess.Popen(
        ['ros2', 'run', '--prefix', 'env SP_PREFIX=yes', 'sp_fake', 'probe'], stdout=subprocess.PIPE, text=True
    )
    assert _read_line(process).endswith('prefix=yes args=')
    process.kill()
    process.wait(10)


def ros2(*words: str, timeout_s: float = 30.0) -> subprocess.CompletedProcess:
    """`ros2 WORDS...` run to its end, its output captured as text."""
    return subprocess.run(['ros2', *words], capture_output=True, text=True, timeout=timeout_s)


@contextlib.contextmanager
def spinning_node(name: str):
    """A node of this process spinning in a thread (its own context) while the `ros2` command runs."""
    import rclpy
    from rclpy.executors import SingleThreadedExecutor

    context = rclpy.Context()
    rclpy.init(context=context)
    node = rclpy.create_node(name, context=context)
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(node)
    thread = threading.Thread(target=executor.spin, daemon=True)
    thread.start()
    try:
        yield node
    finally:
        executor.shutdown()
        node.destroy_node()
        rclpy.shutdown(context=context)
        thread.join(5)


@pytest.fixture
def talker():
    """A BallState publisher at 50 Hz."""
    from stylepong_msgs.msg import BallState

    def publish():
        msg = BallState()
        msg.header.frame_id = 'world'
        msg.position.x = -0.5
        msg.velocity.z = 1.25
        publisher.publish(msg)

    with spinning_node('ros2_command_test_talker') as node:
        publisher = node.create_publisher(BallState, '/test/ball', 10)
        node.create_timer(0.02, publish)
        yield


@pytest.mark.slow  # over 10 s on the 2-core machine: .ci/run runs it, `make test` skips it
def test_topic_list_echo_hz(talker):
    listing = ros2('topic', 'list', '-t').stdout
    assert '/test/ball [stylepong_msgs/msg/BallState]' in listing.splitlines()

    echo = ros2('topic', 'echo', '/test/ball', '--once').stdout
    assert re.search(
        r'^header:\n  stamp:\n    sec: 0\n    nanosec: 0\n  frame_id: world\nposition:\n  x: -0\.5\n', echo
    ), echo
    assert echo.rstrip().endswith('---')
    assert 'z: 1.25' in echo

    hz = subprocess.Popen(
        ['ros2', 'topic', 'hz', '/test/ball'], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True
    )
    # Three reports after the topic is discovered (which can take one 3 s announcement period).
    lines, deadline = [], time.monotonic() + 20.0
    while sum(line.startswith('average rate') for line in lines) < 3 and time.monotonic() < deadline:
        if select.select([hz.stdout], [], [], max(0.0, deadline - time.monotonic()))[0]:
            lines.append(hz.stdout.readline())
    hz.send_signal(signal.SIGINT)
    rest, err = hz.communicate(timeout=10)
    out = ''.join(lines) + rest
    assert hz.returncode == 0 and 'Traceback' not in err, err
    rates = [float(r) for r in re.findall(r'average rate: ([0-9.]+)', out)]
    assert rates, out
    assert 40.0 < rates[-1] < 60.0
    assert re.search(r'\tmin: [0-9.]+s max: [0-9.]+s std dev: [0-9.]+s window: \d+', out)


@pytest.fixture
def trigger_server():
    """A std_srvs/Trigger service that counts its calls."""
    from std_srvs.srv import Trigger

    calls = []

    def handle(request, response):
        calls.append(request)
        response.success = True
        response.message = f'call {len(calls)}'
        return response

    with spinning_node('ros2_command_test_server') as node:
        node.create_service(Trigger, '/test/trigger', handle)
        yield calls


def test_service_list_and_call(trigger_server):
    listing = ros2('service', 'list', '-t').stdout
    assert '/test/trigger [std_srvs/srv/Trigger]' in listing.splitlines()
    out = ros2('service', 'call', '/test/trigger', 'std_srvs/srv/Trigger').stdout
    assert 'requester: making request: std_srvs.srv.Trigger_Request()' in out
    assert "response:\nstd_srvs.srv.Trigger_Response(success=True, message='call 1')" in out
    assert len(trigger_server) == 1


@pytest.fixture
def listener():
    """Subscriptions that keep what arrives on /test/enable (Bool) and /test/array (Float64MultiArray)."""
    from std_msgs.msg import Bool, Float64MultiArray

    received = {'/test/enable': [], '/test/array': []}
    with spinning_node('ros2_command_test_listener') as node:
        for topic, kind in (('/test/enable', Bool), ('/test/array', Float64MultiArray)):
            node.create_subscription(kind, topic, lambda msg, t=topic: received[t].append((time.monotonic(), msg)), 10)
        yield received


def _wait_for(predicate, timeout_s: float = 5.0) -> bool:
    deadline = time.monotonic() + timeout_s
    while not predicate() and time.monotonic() < deadline:
        time.sleep(0.02)
    return predicate()


def test_topic_pub_once_enables_like_ros2cli(listener):
    # The command README gives for enabling the player, on a topic of the test's own.
    result = ros2('topic', 'pub', '--once', '/test/enable', 'std_msgs/msg/Bool', '{data: true}')
    assert result.returncode == 0, result.stderr
    assert 'publishing #1: std_msgs.msg.Bool(data=True)' in result.stdout
    # --once waits for the subscription before publishing, so the one message is not lost.
    assert _wait_for(lambda: listener['/test/enable'])
    time.sleep(0.3)
    assert [msg.data for _, msg in listener['/test/enable']] == [True]


def test_topic_pub_times_rate_and_nested_fields(listener):
    values = '{layout: {dim: [{label: joints, size: 3, stride: 3}], data_offset: 1}, data: [1, 2.5, -3]}'
    result = ros2('topic', 'pub', '-t', '3', '-r', '20', '/test/array', 'std_msgs/msg/Float64MultiArray', values)
    assert result.returncode == 0, result.stderr
    assert result.stdout.count('publishing #') == 3
    assert _wait_for(lambda: len(listener['/test/array']) >= 3)
    arrivals = [t for t, _ in listener['/test/array']]
    # Three messages at 20 Hz span two periods (0.1 s); a loaded machine may stretch, never shrink, them.
    assert arrivals[-1] - arrivals[0] > 0.07
    msg = listener['/test/array'][-1][1]
    assert list(msg.data) == [1.0, 2.5, -3.0]  # YAML's int 1 became the double the field holds
    assert msg.layout.data_offset == 1
    assert [(d.label, d.size, d.stride) for d in msg.layout.dim] == [('joints', 3, 3)]


@pytest.mark.parametrize(
    'values, complaint',
    [
        ('{dat: true}', "has no attribute 'dat'"),
        ('{data: 3}', 'expected true or false'),
        ('[true]', 'expected a mapping'),
    ],
)
def test_topic_pub_refuses_a_bad_message_before_publishing(values, complaint):
    result = ros2('topic', 'pub', '--once', '/test/never', 'std_msgs/msg/Bool', values)
    assert result.returncode != 0
    assert complaint in result.stderr
    assert 'publishing' not in result.stdout
