"""Test isolation for the whole suite (package unit tests and system tests alike).

Every pytest process gets its own ROS_DOMAIN_ID and keeps DDS traffic on the loopback interface, so
suites running side by side (or a developer's live node graph) never see each other's topics.
System tests that start nodes ask for `ros_env`, which gives each test a fresh domain of its own, or
`module_ros_domain` for nodes a whole module shares.
"""

import os
import random
import signal

import pytest

_DOMAIN_RNG = random.Random(os.getpid() ^ int.from_bytes(os.urandom(4), 'little'))


def fresh_domain_id() -> int:
    # 1-101: the range whose DDS ports never collide with the ephemeral range on Linux.
    return _DOMAIN_RNG.randint(1, 101)


os.environ['ROS_DOMAIN_ID'] = str(fresh_domain_id())
os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
os.environ.pop('ROS_LOCALHOST_ONLY', None)
os.environ.setdefault('MUJOCO_GL', 'egl')
# Before torch loads: OpenMP threads that spin while waiting starve every other process on a 2-core
# machine (a 5 s PPO test took 80 s next to a training run).
os.environ.setdefault('OMP_WAIT_POLICY', 'PASSIVE')
# A suite started in the background by a non-interactive shell (`make test &`, some CI runners)
# inherits SIGINT ignored, and so would every node it starts: the Ctrl-C tests would then test nothing.
if signal.getsignal(signal.SIGINT) == signal.SIG_IGN:
    signal.signal(signal.SIGINT, signal.default_int_handler)


@pytest.fixture
def ros_env(monkeypatch):
    """A fresh ROS domain for one test; child processes started with os.environ inherit it."""
    domain = str(fresh_domain_id())
    monkeypatch.setenv('ROS_DOMAIN_ID', domain)
    return dict(os.environ)


@pytest.fixture(scope='module')
def module_ros_domain():
    """A fresh ROS domain shared by one test module (for module-scoped node fixtures)."""
    with pytest.MonkeyPatch.context() as patch:
        patch.setenv('ROS_DOMAIN_ID', str(fresh_domain_id()))
        yield os.environ['ROS_DOMAIN_ID']
