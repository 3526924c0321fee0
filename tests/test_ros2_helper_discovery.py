"""How the `ros2` helper (stylepong_ros2cli.helper, run as tools/ros2) decides that discovery is complete.

A participant's publications and subscriptions reach a new participant through separate DDS
endpoint-discovery exchanges, which a loaded machine can deliver more than a second apart (CI once listed
the cell's publishers without its subscriptions). So the helper reads `ros_discovery_info`, where every ROS
participant names the GIDs of all its nodes' readers and writers, and waits until each of them has been
discovered. These tests check that decision on synthetic GIDs, the wait itself with the discovery state
faked (it must outlast a quiet graph that is still incomplete), and the reader against a node running in
another process (the GIDs it names must be those the graph reports, byte for byte).
"""

import subprocess
import sys
import time

import pytest
from rmw_dds_common.msg import Gid, NodeEntitiesInfo, ParticipantEntitiesInfo

from stylepong_common.node_process import wait_until


@pytest.fixture(scope='module')
def helper():
    """The helper's module, as tools/ros2 runs it."""
    from stylepong_ros2cli import helper

    return helper


def _prefix(participant: int) -> bytes:
    return b'\x01\x0f' + participant.to_bytes(10, 'big')


def _gid(participant: int, entity: int, kind: int) -> bytes:
    """A DDS GUID: the participant's 12-byte prefix, then the entity (kind 0x03 a writer, 0x04 a reader)."""
    return _prefix(participant) + entity.to_bytes(3, 'big') + bytes([kind])


# A participant like the cell's: its discovery-info writer, then one node's writers and readers.
CELL = 7
CELL_DISCOVERY_WRITER = _gid(CELL, 1, 0x03)
CELL_WRITERS = {_gid(CELL, entity, 0x03) for entity in (3, 4, 6, 19, 20)}
CELL_READERS = {_gid(CELL, entity, 0x04) for entity in (5, 24, 25)}


def _info(participant: int, readers: set, writers: set) -> ParticipantEntitiesInfo:
    node = NodeEntitiesInfo(
        node_namespace='/',
        node_name='ur5_sim',
        reader_gid_seq=[Gid(data=list(g)) for g in sorted(readers)],
        writer_gid_seq=[Gid(data=list(g)) for g in sorted(writers)],
    )
    return ParticipantEntitiesInfo(
        gid=Gid(data=list(_prefix(participant) + b'\x00\x00\x01\xc1')), node_entities_info_seq=[node]
    )


def test_a_participant_is_undiscovered_until_every_endpoint_its_info_names_is_discovered(helper):
    named = {_prefix(CELL): helper._named_endpoints(_info(CELL, CELL_READERS, CELL_WRITERS))}
    assert named[_prefix(CELL)] == CELL_READERS | CELL_WRITERS
    writers = {CELL_DISCOVERY_WRITER}
    # The CI failure: the publications discovered, the subscriptions not yet.
    assert helper._undiscovered_participants(writers, named, writers | CELL_WRITERS) == [_prefix(CELL)]
    assert helper._undiscovered_participants(writers, named, writers | CELL_WRITERS | CELL_READERS) == []
    # Its discovery info has not arrived: nothing says its endpoints are complete.
    assert helper._undiscovered_participants(writers, {}, writers | CELL_WRITERS | CELL_READERS) == [_prefix(CELL)]
    # It has left (its discovery-info writer with it): its last info no longer counts.
    assert helper._undiscovered_participants(set(), named, set()) == []


class _FakeReader:
    """Hands out the cell's discovery info once, as the ros_discovery_info reader would."""

    def __init__(self, infos):
        self.infos, self.closed = list(infos), False

    def take(self):
        infos, self.infos = self.infos, []
        return infos

    def close(self):
        self.closed = True


def _fake_discovery(monkeypatch, helper, readers_after_s: float) -> _FakeReader:
    """The cell's writers are discovered at once, its readers only readers_after_s later."""
    reader = _FakeReader([_info(CELL, CELL_READERS, CELL_WRITERS)])
    start = time.monotonic()

    def discovered_endpoints(_node):
        endpoints = {CELL_DISCOVERY_WRITER} | CELL_WRITERS
        if time.monotonic() - start >= readers_after_s:
            endpoints |= CELL_READERS
        return endpoints, {CELL_DISCOVERY_WRITER}

    monkeypatch.setattr(helper, '_open_discovery_info_reader', lambda _node: reader)
    monkeypatch.setattr(helper, '_discovered_endpoints', discovered_endpoints)
    return reader


def _timed_wait(helper, monkeypatch, node_name: str, readers_after_s: float) -> tuple[float, _FakeReader]:
    """Seconds `_wait_for_graph` (spin time 0.2 s) takes on a fresh helper node whose faked discovery
    shows the remote readers readers_after_s after the node starts; and the fake reader."""
    rclpy, node = helper._start_node(node_name)
    try:
        reader = _fake_discovery(monkeypatch, helper, readers_after_s=readers_after_s)
        started = time.monotonic()
        helper._wait_for_graph(node, spin_time=0.2)
        return time.monotonic() - started, reader
    finally:
        helper._stop_node(rclpy, node)


def test_the_wait_outlasts_a_quiet_graph_until_the_named_endpoints_are_discovered(helper, ros_env, monkeypatch):
    # The node's own graph (a domain of its own) stays unchanged: the settle rule alone would return after
    # spin_time + GRAPH_SETTLE_S = 0.7 s, without the cell's subscriptions.
    waited, reader = _timed_wait(helper, monkeypatch, '_ros2_helper_wait_test', readers_after_s=2.0)
    assert 2.0 <= waited < 2.0 + 1.0, waited
    assert reader.closed


def test_the_wait_gives_up_on_an_incomplete_graph_after_the_hard_cap(helper, ros_env, monkeypatch):
    monkeypatch.setattr(helper, 'GRAPH_MAX_EXTRA_S', 1.0)
    waited, _ = _timed_wait(helper, monkeypatch, '_ros2_helper_cap_test', readers_after_s=float('inf'))
    assert 1.2 <= waited < 1.2 + 1.0, waited


# A node in another process, with a publisher, a subscription and a service.
PROBE_NODE = """
import rclpy
from std_msgs.msg import String
from std_srvs.srv import Trigger
rclpy.init()
node = rclpy.create_node('discovery_probe')
node.create_publisher(String, 'probe_out', 10)
node.create_subscription(String, 'probe_in', lambda _msg: None, 10)
node.create_service(Trigger, 'probe_service', lambda _request, response: response)
print('ready', flush=True)
rclpy.spin(node)
"""


@pytest.fixture
def probe_node(ros_env):
    process = subprocess.Popen([sys.executable, '-c', PROBE_NODE], stdout=subprocess.PIPE, text=True)
    try:
        assert process.stdout.readline().strip() == 'ready'
        yield process
    finally:
        process.kill()
        process.wait(10)


def test_the_reader_gets_the_info_of_a_node_in_another_process(helper, probe_node):
    rclpy, node = helper._start_node('_ros2_helper_reader_test')
    reader = helper._open_discovery_info_reader(node)
    try:
        assert reader is not None  # rmw reached through ctypes
        infos = {}

        def spin():
            rclpy.spin_once(node, timeout_sec=0.05)
            infos.update((bytes(i.gid.data)[:12], i) for i in reader.take())

        def probe_subscription():
            found = node.get_subscriptions_info_by_topic('/probe_in')
            return bytes(found[0].endpoint_gid) if found else None

        assert wait_until(lambda: probe_subscription() is not None, 30.0, spin=spin)
        probe_prefix = probe_subscription()[:12]
        assert wait_until(lambda: probe_prefix in infos, 30.0, spin=spin)
        info = infos[probe_prefix]
        assert [n.node_name for n in info.node_entities_info_seq] == ['discovery_probe']
        named = helper._named_endpoints(info)
        # The GIDs in the message and those rclpy reports are the same 16 bytes.
        assert probe_subscription() in named
        named_by_prefix = {prefix: helper._named_endpoints(i) for prefix, i in infos.items()}

        def complete():
            endpoints, discovery_info_writers = helper._discovered_endpoints(node)
            return probe_prefix in {g[:12] for g in discovery_info_writers} and not helper._undiscovered_participants(
                discovery_info_writers, named_by_prefix, endpoints
            )

        assert wait_until(complete, 30.0, spin=spin)
        # Its publisher, subscription, service and parameter services: request readers and reply writers too.
        endpoints, _ = helper._discovered_endpoints(node)
        assert len(named) >= 1 + 1 + 2 + 2 * 6 and named <= endpoints
    finally:
        reader.close()
        helper._stop_node(rclpy, node)


def test_topic_list_returns_once_the_graph_is_complete_not_at_the_cap(helper, probe_node):
    started = time.monotonic()
    run = subprocess.run(['ros2', 'topic', 'list'], capture_output=True, text=True, timeout=60)
    took = time.monotonic() - started
    assert run.returncode == 0 and not run.stderr, run
    assert {'/probe_in', '/probe_out'} <= set(run.stdout.split()), run.stdout
    # About spin time + settling (4 s). A GID format mismatch would never let the graph count as complete:
    # the wait would run to its cap.
    assert took < helper.DEFAULT_SPIN_TIME_S + helper.GRAPH_MAX_EXTRA_S, took


def test_an_error_after_a_stop_signal_ends_the_verb_quietly(helper, monkeypatch):
    # SIGTERM while rclpy converts a received message surfaces as pybind11's RuntimeError, not _Stopped.
    def interrupted(_argv):
        raise RuntimeError('Unable to convert call argument')

    monkeypatch.setattr(helper, '_stop_signal', None)
    with pytest.raises(RuntimeError):  # without a stop signal, an error is an error
        helper._run_graph_verb(interrupted, [])
    monkeypatch.setattr(helper, '_stop_signal', 'SIGTERM')
    assert helper._run_graph_verb(interrupted, []) == 0
