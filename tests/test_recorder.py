"""System tests of `ros2 run stylepong_recording recorder` and `recover_bag` through real topics and services.

The test publishes JointState at 500 Hz itself (reliable, depth 10: what the UR driver's
joint_state_broadcaster and ur5_sim offer), each message named by a unique header stamp, and keeps
when it published which; then it reads the bag back with rosbags and with the mcap + mcap-ros2-support
readers and compares stamps.
"""

import contextlib
import random
import shutil
import signal
import subprocess
import threading
import time
from pathlib import Path

import pytest
import rclpy
from rclpy.node import Node
from rclpy.qos import QoSPresetProfiles, QoSProfile, ReliabilityPolicy
from rosbags.highlevel import AnyReader
from sensor_msgs.msg import JointState
from std_srvs.srv import Trigger

from stylepong_common.node_process import NodeProcess, wait_until
from stylepong_msgs.msg import BallState
from stylepong_msgs.srv import StartClip
from stylepong_recording.bag_check import (
    JOINT_NAMES,
    JOINT_STATES,
    read_with_mcap_ros2,
    read_with_rosbags,
    read_with_sqlite3,
    storage_file,
)

RATE_HZ = 500.0
# The recorder flushes every 0.1 s, so a killed recorder loses at most that much (docs/DESIGN.md, "Recorder
# flush and recovery"); a message counts from when it reaches the recorder, which on this machine is within
# DELIVERY_S of its publication.
FLUSH_PERIOD_S = 0.1
DELIVERY_S = 0.02


class JointStatePublisher:
    """Publishes JointState at RATE_HZ from a thread; records (stamp_ns, monotonic publish time)."""

    def __init__(self, node: Node):
        self._pub = node.create_publisher(
            JointState, JOINT_STATES, QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE)
        )
        self.published: list[tuple[int, float]] = []
        self._lock = threading.Lock()
        self._running = True
        self._thread = threading.Thread(target=self._run, daemon=True)
        self._thread.start()

    def _run(self) -> None:
        msg = JointState(name=list(JOINT_NAMES), position=[0.0] * 6, velocity=[0.0] * 6, effort=[0.0] * 6)
        period_s = 1.0 / RATE_HZ
        next_s = time.monotonic()
        index = 0
        while self._running:
            index += 1
            # A unique, increasing stamp per message, as a 500 Hz driver's steady header stamps.
            stamp_ns = 1_000_000_000 + index * 2_000_000
            msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(stamp_ns, 1_000_000_000)
            msg.position[0] = index * 1e-3
            self._pub.publish(msg)
            with self._lock:
                self.published.append((stamp_ns, time.monotonic()))
            next_s += period_s
            delay_s = next_s - time.monotonic()
            if delay_s > 0:
                time.sleep(delay_s)

    def stamps_between(self, start_s: float, end_s: float) -> list[int]:
        return [stamp for stamp, _ in self.published_between(start_s, end_s)]

    def published_between(self, start_s: float, end_s: float) -> list[tuple[int, float]]:
        with self._lock:
            return [(stamp, t) for stamp, t in self.published if start_s <= t <= end_s]

    def stop(self) -> None:
        self._running = False
        self._thread.join(5.0)


class Harness:
    def __init__(self):
        self.node = rclpy.create_node('recorder_test')
        self.start_client = self.node.create_client(StartClip, '/recorder/start')
        self.stop_client = self.node.create_client(Trigger, '/recorder/stop')
        self.publisher: JointStatePublisher | None = None

    def publish_joint_states(self) -> JointStatePublisher:
        self.publisher = JointStatePublisher(self.node)
        return self.publisher

    def call(self, client, request, timeout_s=20.0):
        assert client.wait_for_service(timeout_sec=timeout_s), f'{client.srv_name} not available'
        future = client.call_async(request)
        rclpy.spin_until_future_complete(self.node, future, timeout_sec=timeout_s)
        assert future.done(), f'{client.srv_name} did not answer'
        return future.result()

    def start(self, label):
        return self.call(self.start_client, StartClip.Request(label=label))

    def stop(self):
        return self.call(self.stop_client, Trigger.Request())

    def begin_clip(self, recorder: NodeProcess, label: str):
        """Joint states flowing for 0.5 s, then /recorder/start: (publisher, response, monotonic start)."""
        self.wait_for_subscriber(recorder)
        publisher = self.publish_joint_states()
        time.sleep(0.5)
        response = self.start(label)
        return publisher, response, time.monotonic()

    def wait_for_subscriber(self, recorder: NodeProcess, timeout_s=30.0):
        assert wait_until(lambda: self.node.count_subscribers(JOINT_STATES) > 0 or not recorder.running(), timeout_s), (
            'the recorder never subscribed to /joint_states'
        )
        assert recorder.running(), recorder.output()


@pytest.fixture
def harness(ros_env):
    rclpy.init()
    harness = Harness()
    yield harness
    if harness.publisher is not None:
        harness.publisher.stop()
    harness.node.destroy_node()
    rclpy.shutdown()


def assert_published_payloads(joint_states) -> None:
    """Each decoded JointState is the one JointStatePublisher sent with its stamp: names, and position[0]
    = index * 1e-3 where stamp = 1 s + index * 2 ms."""
    assert joint_states
    for js in joint_states:
        index = (js.stamp_ns - 1_000_000_000) // 2_000_000
        assert js.name == list(JOINT_NAMES) and len(js.position) == len(js.velocity) == len(js.effort) == 6
        assert js.position == [index * 1e-3, 0.0, 0.0, 0.0, 0.0, 0.0], js


def start_recorder(output_dir: Path, **params) -> NodeProcess:
    return NodeProcess('stylepong_recording', 'recorder', params={'output_dir': str(output_dir), **params}).start()


@contextlib.contextmanager
def recording_clip(harness: Harness, output_dir: Path, storage: str, label: str):
    """A recorder writing `storage` bags into output_dir, joint states flowing and a clip `label` started (the
    start checked): yields (recorder, publisher, the clip's bag directory, monotonic start); the recorder is
    stopped on the way out."""
    recorder = start_recorder(output_dir, storage=storage)
    try:
        publisher, response, started_s = harness.begin_clip(recorder, label)
        assert response.success, response.message
        yield recorder, publisher, Path(response.bag_path), started_s
    finally:
        recorder.stop()


@pytest.mark.parametrize('storage', ['mcap', 'sqlite3'])
def test_a_clip_holds_the_published_joint_states_and_its_label(harness, tmp_path, storage):
    with recording_clip(harness, tmp_path / 'bags', storage, 'forward') as (recorder, publisher, bag_dir, started_s):
        assert bag_dir.parent == tmp_path / 'bags' and bag_dir.name.startswith('forward_')
        time.sleep(3.0)
        stopping_s = time.monotonic()
        stopped = harness.stop()
        publisher.stop()
        assert stopped.success, stopped.message
        assert recorder.running(), recorder.output()

    published = publisher.stamps_between(started_s, stopping_s)
    assert len(published) > 0.8 * 3.0 * RATE_HZ, 'the test publisher itself fell behind'
    content = read_with_rosbags(bag_dir)
    assert content.custom_data == {'label': 'forward'}
    recorded = content.stamps[JOINT_STATES]
    kept = len(set(published) & set(recorded)) / len(published)
    print(f'{storage}: kept {kept:.4f} of {len(published)} joint states published during the clip')
    assert kept >= 0.99
    assert recorded == sorted(recorded), 'joint states out of order'
    assert content.metadata_counts[JOINT_STATES] == len(recorded)
    if storage == 'mcap':
        mcap = read_with_mcap_ros2(storage_file(bag_dir, '.mcap'))
        assert mcap.stamps[JOINT_STATES] == recorded
        assert mcap.log_times[JOINT_STATES] == content.log_times[JOINT_STATES]
    else:
        sql, joint_states = read_with_sqlite3(storage_file(bag_dir, '.db3'))
        assert sql.custom_data == {'label': 'forward'}
        assert sql.stamps[JOINT_STATES] == recorded
        assert sql.log_times[JOINT_STATES] == content.log_times[JOINT_STATES]
        assert sql.metadata_counts[JOINT_STATES] == len(recorded)
        assert_published_payloads(joint_states)


@pytest.mark.parametrize('storage', ['mcap', 'sqlite3'])
def test_after_sigkill_recover_bag_gives_every_joint_state_up_to_0_1_s_before_the_kill(harness, tmp_path, storage):
    with recording_clip(harness, tmp_path / 'bags', storage, 'leftward') as (recorder, publisher, bag_dir, started_s):
        # The kill lands anywhere in the recorder's 0.1 s flush cycle (a fixed 3 s would always hit one phase).
        time.sleep(3.0 + random.uniform(0.0, FLUSH_PERIOD_S))
        killed_s = time.monotonic()
        recorder.signal(signal.SIGKILL)
        recorder.process.wait(10.0)
        publisher.stop()
    assert not (bag_dir / 'metadata.yaml').exists()  # the kill really left an unfinished bag

    result = subprocess.run(
        ['ros2', 'run', 'stylepong_recording', 'recover_bag', str(bag_dir)], capture_output=True, text=True, timeout=120
    )
    assert result.returncode == 0, result.stdout + result.stderr
    assert 'recovered' in result.stdout

    content = read_with_rosbags(bag_dir)
    assert content.custom_data == {'label': 'leftward'}
    recorded = set(content.stamps[JOINT_STATES])
    must_have = publisher.stamps_between(started_s, killed_s - FLUSH_PERIOD_S - DELIVERY_S)
    missing = [s for s in must_have if s not in recorded]
    published = publisher.published_between(started_s, killed_s)
    first_lost_s = next((t for stamp, t in published if stamp not in recorded), killed_s)
    print(
        f'{storage}: {len(recorded)} joint states recovered; {len(missing)} of the {len(must_have)} '
        f'published up to {FLUSH_PERIOD_S + DELIVERY_S:.2f} s before the kill are missing; '
        f'lost: what was published in the last {killed_s - first_lost_s:.3f} s'
    )
    assert len(must_have) > 2.0 * RATE_HZ
    assert not missing
    if storage == 'mcap':
        assert set(read_with_mcap_ros2(storage_file(bag_dir, '.mcap')).stamps[JOINT_STATES]) == recorded
    else:
        sql, joint_states = read_with_sqlite3(storage_file(bag_dir, '.db3'))
        assert set(sql.stamps[JOINT_STATES]) == recorded
        assert sql.custom_data == {'label': 'leftward'}
        assert_published_payloads(joint_states)

    again = subprocess.run(
        ['ros2', 'run', 'stylepong_recording', 'recover_bag', str(bag_dir)], capture_output=True, text=True, timeout=120
    )
    assert again.returncode == 0 and 'healthy, left unchanged' in again.stdout, again.stdout + again.stderr


def test_sigint_closes_the_clip_cleanly(harness, tmp_path):
    recorder = start_recorder(tmp_path / 'bags')
    try:
        harness.wait_for_subscriber(recorder)
        publisher = harness.publish_joint_states()
        response = harness.start('rightward')
        assert response.success, response.message
        time.sleep(1.0)
    finally:
        exit_code = recorder.stop(timeout_s=20.0)
        publisher.stop()
    assert exit_code == 0, recorder.output()
    bag_dir = Path(response.bag_path)
    assert (bag_dir / 'metadata.yaml').is_file()
    assert not (bag_dir / 'recording_in_progress.yaml').exists()
    content = read_with_rosbags(bag_dir)
    assert content.custom_data == {'label': 'rightward'}
    assert len(content.stamps[JOINT_STATES]) > 0.5 * RATE_HZ
    assert read_with_mcap_ros2(storage_file(bag_dir, '.mcap')).stamps == content.stamps


def test_bad_requests_are_refused_with_the_reason_and_the_node_keeps_recording(harness, tmp_path):
    a_file = tmp_path / 'a_file'
    a_file.write_text('not a directory')
    recorder = start_recorder(tmp_path / 'bags')
    # Two more recorders in their own namespaces: one whose output_dir cannot exist, one on a "full" disk.
    unwritable = NodeProcess(
        'stylepong_recording',
        'recorder',
        '--ros-args',
        '-r',
        '__ns:=/unwritable',
        params={'output_dir': str(a_file / 'bags')},
    ).start()
    full = NodeProcess(
        'stylepong_recording',
        'recorder',
        '--ros-args',
        '-r',
        '__ns:=/full',
        params={'output_dir': str(tmp_path / 'full'), 'min_free_space_mb': 1e9},
    ).start()
    try:
        harness.wait_for_subscriber(recorder)
        stop = harness.stop()
        assert not stop.success and 'not recording' in stop.message
        for label, reason in [
            ('', 'empty'),
            ('../escape', 'path separator'),
            ('a/b', 'path separator'),
            ('.hidden', 'starts with'),
        ]:
            response = harness.start(label)
            assert not response.success and reason in response.message, response.message

        for namespace, reason in [('/unwritable', 'cannot be created'), ('/full', 'disk full')]:
            client = harness.node.create_client(StartClip, f'{namespace}/recorder/start')
            response = harness.call(client, StartClip.Request(label='forward'))
            assert not response.success and reason in response.message, response.message
        assert not (tmp_path / 'full').exists() or not any((tmp_path / 'full').iterdir())

        first = harness.start('forward')
        assert first.success, first.message
        again = harness.start('leftward')
        assert not again.success and 'already recording' in again.message
        assert again.bag_path == first.bag_path
        assert harness.stop().success
        assert harness.start('leftward').success and harness.stop().success
        assert sorted(p.name.split('_')[0] for p in (tmp_path / 'bags').iterdir()) == ['forward', 'leftward']
        assert recorder.running() and unwritable.running() and full.running()
    finally:
        for process in (recorder, unwritable, full):
            process.stop()


def test_best_effort_publishers_and_extra_topics_of_project_types_are_recorded(harness, tmp_path):
    """A sensor-QoS /joint_states (a reliable reader would never match it) and a /ball/state of the
    project's own message type, listed in `topics` and published only after the recorder started."""
    recorder = NodeProcess(
        'stylepong_recording',
        'recorder',
        '--ros-args',
        '-p',
        'topics:=[/ball/state]',
        params={'output_dir': str(tmp_path / 'bags')},
    ).start()
    node = harness.node
    try:
        harness.wait_for_subscriber(recorder)
        joints = node.create_publisher(JointState, JOINT_STATES, QoSPresetProfiles.SENSOR_DATA.value)
        balls = node.create_publisher(BallState, '/ball/state', 10)

        def recorder_adapted():
            infos = node.get_subscriptions_info_by_topic(JOINT_STATES)
            return (
                node.count_subscribers('/ball/state') > 0
                and len(infos) == 1
                and infos[0].qos_profile.reliability == ReliabilityPolicy.BEST_EFFORT
            )

        assert wait_until(recorder_adapted, 30.0), recorder.output()
        time.sleep(0.3)
        response = harness.start('forward')
        assert response.success, response.message
        published = []
        for i in range(1, 301):  # 1.5 s: joint states at 200 Hz, balls at 100 Hz
            msg = JointState(name=list(JOINT_NAMES), position=[i * 1e-3] * 6)
            msg.header.stamp.sec, msg.header.stamp.nanosec = 7, i
            joints.publish(msg)
            published.append(i)
            if i % 2 == 0:
                ball = BallState()
                ball.header.stamp.sec, ball.header.stamp.nanosec = 7, i
                ball.header.frame_id = 'world'
                ball.position.x, ball.velocity.z = i * 0.01, -1.0
                balls.publish(ball)
            time.sleep(0.005)
        time.sleep(0.2)
        stopped = harness.stop()
        assert stopped.success, stopped.message
    finally:
        recorder.stop()

    bag_dir = Path(response.bag_path)
    for content in (read_with_rosbags(bag_dir), read_with_mcap_ros2(storage_file(bag_dir, '.mcap'))):
        joint_stamps = [s - 7_000_000_000 for s in content.stamps[JOINT_STATES]]
        assert len(set(joint_stamps) & set(published)) >= 0.9 * len(published)
        assert [s - 7_000_000_000 for s in content.stamps['/ball/state']] == list(range(2, 301, 2))
    with AnyReader([bag_dir]) as reader:
        ball_connection = next(c for c in reader.connections if c.topic == '/ball/state')
        assert ball_connection.msgtype == 'stylepong_msgs/msg/BallState'
        first = reader.deserialize(next(reader.messages([ball_connection]))[2], ball_connection.msgtype)
        assert first.header.frame_id == 'world' and first.position.x == pytest.approx(0.02)
        assert first.velocity.z == -1.0


@pytest.fixture
def tiny_disk(tmp_path):
    """A 256 KiB file system (tmpfs), where a 500 Hz clip fills the disk within about a second."""
    mount_point = tmp_path / 'tiny_disk'
    mount_point.mkdir()
    mounted = subprocess.run(
        ['mount', '-t', 'tmpfs', '-o', 'size=256k', 'tmpfs', str(mount_point)], capture_output=True, text=True
    )
    if mounted.returncode != 0:
        pytest.skip(f'cannot mount a small tmpfs here (needs root): {mounted.stderr.strip()}')
    yield mount_point
    subprocess.run(['umount', '-l', str(mount_point)], check=False)


def test_a_full_disk_stops_the_clip_with_the_reason_and_the_node_keeps_running(harness, tiny_disk):
    recorder = start_recorder(tiny_disk / 'bags', min_free_space_mb=0.0)
    try:
        harness.wait_for_subscriber(recorder)
        harness.publish_joint_states()
        time.sleep(0.3)
        response = harness.start('forward')
        assert response.success, response.message
        bag_dir = Path(response.bag_path)
        # The clip ends itself when a write fails; /recorder/stop then reports why.
        assert wait_until(lambda: 'disk full' in recorder.output() or not recorder.running(), 60.0)
        stopped = harness.stop()
        assert not stopped.success and 'disk full' in stopped.message, stopped.message
        assert 'recover_bag' in stopped.message
        # A new clip on the full disk is refused with the reason; the node is still there.
        again = harness.start('forward')
        assert not again.success and 'disk full' in again.message, again.message
        assert recorder.running(), recorder.output()
    finally:
        recorder.stop()
    # What reached the disk is kept; recovering needs room for a copy, so move the bag off the tiny disk.
    rescued = shutil.copytree(bag_dir, tiny_disk.parent / bag_dir.name)
    result = subprocess.run(
        ['ros2', 'run', 'stylepong_recording', 'recover_bag', str(rescued)], capture_output=True, text=True, timeout=120
    )
    assert result.returncode == 0, result.stdout + result.stderr
    content = read_with_rosbags(rescued)
    assert content.custom_data == {'label': 'forward'} and len(content.stamps[JOINT_STATES]) > 100
