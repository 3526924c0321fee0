"""Start real nodes with `ros2 run` for system tests, and stop them the way a person would (Ctrl-C)."""
from __future__ import annotations

import os
import pathlib
import signal
import subprocess
import tempfile
import time


class NodeProcess:
    """`ros2 run <package> <executable> [args]` as a child process with its output in a log file."""

    def __init__(self, package: str, executable: str, *args: str, params: dict | None = None,
                 env: dict | None = None):
        self.command = ['ros2', 'run', package, executable, *args]
        if params:
            self.command += ['--ros-args'] + [a for k, v in params.items() for a in ('-p', f'{k}:={_param(v)}')]
        self.env = dict(os.environ if env is None else env)
        self.env.setdefault('PYTHONUNBUFFERED', '1')
        self.log_path = pathlib.Path(tempfile.mkstemp(prefix=f'{executable}_', suffix='.log')[1])
        self.process: subprocess.Popen | None = None

    def start(self) -> 'NodeProcess':
        self._log = open(self.log_path, 'w')
        self.process = subprocess.Popen(self.command, stdout=self._log, stderr=subprocess.STDOUT, env=self.env,
                                        start_new_session=True)
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
        if self.running():
            self.signal(signal.SIGINT)
            try:
                self.process.wait(timeout_s)
            except subprocess.TimeoutExpired:
                self.signal(signal.SIGKILL)
                self.process.wait(timeout_s)
        self._log.close()
        return self.process.returncode

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
