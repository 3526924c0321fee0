"""node_process's helpers on plain processes (no ROS): logged start, Ctrl-C then SIGKILL, CPU time, ports."""

import os
import signal
import socket
import subprocess
import time

from stylepong_common.node_process import free_port, isolated_ros_env, process_cpu_s, start_logged, stop_group


def test_a_started_command_logs_and_stops_on_ctrl_c(tmp_path):
    process = start_logged(['sh', '-c', 'echo started; exec sleep 30'], dict(os.environ), tmp_path / 'log')
    assert os.getpgid(process.pid) == process.pid  # a session of its own: the group gets the Ctrl-C
    deadline = time.monotonic() + 10.0
    while 'started' not in (tmp_path / 'log').read_text() and time.monotonic() < deadline:
        time.sleep(0.02)
    assert stop_group(process, timeout_s=5.0) == -signal.SIGINT
    assert (tmp_path / 'log').read_text() == 'started\n'


def test_a_command_deaf_to_ctrl_c_is_killed_after_the_timeout(tmp_path):
    process = start_logged(
        [
            'python3',
            '-c',
            'import signal, time; signal.signal(signal.SIGINT, signal.SIG_IGN); '
            'print("deaf", flush=True); time.sleep(30)',
        ],
        dict(os.environ),
        tmp_path / 'log',
    )
    deadline = time.monotonic() + 10.0
    while 'deaf' not in (tmp_path / 'log').read_text() and time.monotonic() < deadline:
        time.sleep(0.02)
    started = time.monotonic()
    assert stop_group(process, timeout_s=0.5) == -signal.SIGKILL
    assert time.monotonic() - started < 5.0


def test_cpu_time_grows_with_work_and_is_nan_for_a_process_gone():
    before = process_cpu_s(os.getpid())
    sum(i * i for i in range(2_000_000))
    assert process_cpu_s(os.getpid()) > before
    child = subprocess.Popen(['true'])
    child.wait()
    assert process_cpu_s(child.pid) != process_cpu_s(child.pid)  # NaN


def test_a_free_port_can_be_bound_and_each_run_gets_its_own_domain():
    with socket.socket() as server:
        server.bind(('127.0.0.1', free_port()))
    env = isolated_ros_env()
    assert 1 <= int(env['ROS_DOMAIN_ID']) <= 101 and env['ROS_AUTOMATIC_DISCOVERY_RANGE'] == 'LOCALHOST'
