"""Start real nodes with `ros2 run` for system tests and benchmarks, and stop them the way a person would
(Ctrl-C); what such runs need around them: a ROS domain of their own, free ports, a process's CPU time."""

from __future__ import annotations

import os
import pathlib
import random
import signal
import socket
import subprocess
import tempfile
import time


def isolated_ros_env() -> dict[str, str]:
    """This process's environment with a random ROS domain (1-101: DDS ports clear of Linux's ephemeral
    range) on the loopback only, so that a run never meets another graph; output unbuffered for logs."""
    return dict(
        os.environ,
        ROS_DOMAIN_ID=str(random.randint(1, 101)),
        ROS_AUTOMATIC_DISCOVERY_RANGE='LOCALHOST',
        PYTHONUNBUFFERED='1',
    )


def start_logged(command: list[str], env: dict, log_path: pathlib.Path) -> subprocess.Popen:
    """`command` with its output in log_path, in a session of its own: a Ctrl-C sent to its group also
    reaches the node that `ros2 run` starts as its child."""
    with open(log_path, 'w') as log:  # the child holds its own copy of the descriptor
        return subprocess.Popen(command, stdout=log, stderr=subprocess.STDOUT, env=env, start_new_session=True)


def stop_group(process: subprocess.Popen, timeout_s: float = 20.0) -> int:
    """Ctrl-C (SIGINT) to the process's group, SIGKILL if it has not exited within timeout_s; its exit code."""
    if process.poll() is None:
        os.killpg(process.pid, signal.SIGINT)
        try:
            process.wait(timeout_s)
        except subprocess.TimeoutExpired:
            os.killpg(process.pid, signal.SIGKILL)
            process.wait(timeout_s)
    return process.returncode


def process_cpu_s(pid: int) -> float:
    """CPU time (user + system, s) the process has used so far; NaN once it is gone."""
    try:
        fields = pathlib.Path(f'/proc/{pid}/stat').read_text().rsplit(')', 1)[1].split()
    except OSError:
        return float('nan')
    return (int(fields[11]) + int(fields[12])) / os.sysconf('SC_CLK_TCK')


def free_port() -> int:
    """A TCP port on the loopback that nothing listens on now."""
    with socket.socket() as probe:
        probe.bind(('127.0.0.1', 0))
        return probe.getsockname()[1]


def viewer_command(grpc_port: int, *options: str) -> list[str]:
    """`ros2 run stylepong_viz viewer` on a free web port and this data (gRPC) port, with options; a caller
    that watches the page's data connection picks grpc_port itself."""
    return [
        'ros2',
        'run',
        'stylepong_viz',
        'viewer',
        '--web-port',
        str(free_port()),
        '--grpc-port',
        str(grpc_port),
        *options,
    ]


def run_rally_eval(env: dict, balls: int, first_seed: int, json_path: pathlib.Path) -> subprocess.CompletedProcess:
    """`ros2 run stylepong_sim rally_eval` serving `balls` balls of one seed to the player already running in
    env's graph, its summary written to json_path; the finished process (the caller judges its exit code)."""
    command = ['ros2', 'run', 'stylepong_sim', 'rally_eval', '--seeds', '1', '--balls', str(balls)]
    command += ['--first-seed', str(first_seed), '--json', str(json_path)]
    return subprocess.run(command, env=env, capture_output=True, text=True, timeout=300)


class NodeProcess:
    """`ros2 run <package> <executable> [args]` as a child process with its output in a log file."""

    def __init__(self, package: str, executable: str, *args: str, params: dict | None = None, env: dict | None = None):
        self.command = ['ros2', 'run', package, executable, *args]
        if params:
            self.command += ['--ros-args'] + [a for k, v in params.items() for a in ('-p', f'{k}:={_param(v)}')]
        self.env = dict(os.environ if env is None else env)
        self.env.setdefault('PYTHONUNBUFFERED', '1')
        self.log_path = pathlib.Path(tempfile.mkstemp(prefix=f'{executable}_', suffix='.log')[1])
        self.process: subprocess.Popen | None = None

    def start(self) -> 'NodeProcess':
        self.process = start_logged(self.command, self.env, self.log_path)
        return self

    def running(self) -> bool:
        return self.process is not None and self.process.poll() is None

    def output(self) -> str:
        return self.log_path.read_text(errors='replace')

    def signal(self, sig: int) -> None:
        if self.running():
            os.killpg(self.process.pid, sig)

    def stop(self, timeout_s: float = 5.0) -> int | None:
        """SIGINT, then SIGKILL if the node does not exit within timeout_s. Returns the exit code."""
        if self.process is None:
            return None
        return stop_group(self.process, timeout_s)

    def __enter__(self) -> 'NodeProcess':
        return self.start()

    def __exit__(self, *exc) -> None:
        self.stop()


def _param(value) -> str:
    if isinstance(value, bool):
        return 'true' if value else 'false'
    if isinstance(value, (list, tuple)):
        return '[' + ','.join(_param(v) for v in value) + ']'
    return str(value)


def wait_until(predicate, timeout_s: float, period_s: float = 0.02, spin=None) -> bool:
    """Poll predicate (spinning `spin()` between polls) until true or timeout."""
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        if spin is not None:
            spin()
        if predicate():
            return True
        if spin is None:
            time.sleep(period_s)
    return predicate()
