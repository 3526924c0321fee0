#!/usr/bin/env python3
"""Recorder: what it keeps at 500 Hz, what it costs, what a SIGKILL loses, and bag I/O speed."""

import os
import random
import shutil
import signal
import tempfile
import threading
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
# A fresh DDS domain per recording: a SIGKILLed recorder stays in the graph until its lease expires.
DOMAINS = iter(random.Random(os.getpid()).sample(range(102, 200), 20))

import rclpy  # noqa: E402
import rclpy.executors  # noqa: E402
from geometry_msgs.msg import WrenchStamped  # noqa: E402
from rclpy.qos import QoSProfile, ReliabilityPolicy  # noqa: E402
from sensor_msgs.msg import JointState  # noqa: E402
from std_srvs.srv import Trigger  # noqa: E402

from stylepong_common.node_process import NodeProcess, wait_until  # noqa: E402
from stylepong_msgs.srv import StartClip  # noqa: E402
from stylepong_recording.bag_check import JOINT_STATE_TYPE, JOINT_STATES, joint_state_cdr, read_with_rosbags  # noqa: E402
from stylepong_recording.clip_writer import ClipWriter, TopicSpec  # noqa: E402
from stylepong_recording.msg_definitions import MessageDefinitions  # noqa: E402
from stylepong_recording.recover_bag import recover_bag  # noqa: E402

RATE_HZ = 500.0
WRENCH = '/force_torque_sensor_broadcaster/wrench'


class Publisher:
    """JointState and WrenchStamped at 500 Hz, each with a unique header stamp; keeps publish times."""

    def __init__(self, node):
        qos = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE)
        self.joints = node.create_publisher(JointState, JOINT_STATES, qos)
        self.wrench = node.create_publisher(WrenchStamped, WRENCH, qos)
        self.published = []
        self.running = True
        self.thread = threading.Thread(target=self.run, daemon=True)
        self.thread.start()

    def run(self):
        joints = JointState(name=[f'j{i}' for i in range(6)], position=[0.0] * 6, velocity=[0.0] * 6, effort=[0.0] * 6)
        wrench = WrenchStamped()
        next_s, index = time.monotonic(), 0
        while self.running:
            index += 1
            stamp_ns = 1_000_000_000 + index * 2_000_000
            for msg in (joints, wrench):
                msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(stamp_ns, 1_000_000_000)
            self.joints.publish(joints)
            self.wrench.publish(wrench)
            self.published.append((stamp_ns, time.monotonic()))
            next_s += 1.0 / RATE_HZ
            if (delay := next_s - time.monotonic()) > 0:
                time.sleep(delay)

    def between(self, start_s, end_s):
        return [s for s, t in list(self.published) if start_s <= t <= end_s]

    def stop(self):
        self.running = False
        self.thread.join()


def call(node, client, request):
    assert client.wait_for_service(timeout_sec=30.0)
    future = client.call_async(request)
    executor = rclpy.executors.SingleThreadedExecutor(context=node.context)
    rclpy.spin_until_future_complete(node, future, executor=executor, timeout_sec=30.0)
    assert future.done(), f'{client.srv_name} did not answer'
    return future.result()


def cpu_s(pid):
    fields = Path(f'/proc/{pid}/stat').read_text().rsplit(')', 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf('SC_CLK_TCK')


def record(out, storage, clip_s, kill_at_s=None):
    domain = next(DOMAINS)
    context = rclpy.Context()
    rclpy.init(context=context, domain_id=domain)
    node = rclpy.create_node('bench_recorder', context=context)
    try:
        return _record(node, out, storage, clip_s, kill_at_s, {**os.environ, 'ROS_DOMAIN_ID': str(domain)})
    finally:
        node.destroy_node()
        rclpy.shutdown(context=context)


def _record(node, out, storage, clip_s, kill_at_s, env):
    recorder = NodeProcess(
        'stylepong_recording',
        'recorder',
        '--ros-args',
        '-p',
        f'topics:=[{WRENCH}]',
        params={'output_dir': str(out), 'storage': storage},
        env=env,
    ).start()
    start = node.create_client(StartClip, '/recorder/start')
    stop = node.create_client(Trigger, '/recorder/stop')
    publisher = None
    try:
        assert wait_until(lambda: node.count_subscribers(JOINT_STATES) > 0, 30.0), recorder.output()
        publisher = Publisher(node)
        # The recorder subscribes to the wrench once its 1 s graph discovery has seen the publisher.
        assert wait_until(lambda: node.count_subscribers(WRENCH) > 0, 30.0), recorder.output()
        time.sleep(0.5)
        response = call(node, start, StartClip.Request(label='bench'))
        assert response.success, response.message
        started_s, cpu0 = time.monotonic(), cpu_s(recorder.process.pid)
        if kill_at_s is not None:
            time.sleep(kill_at_s)
            killed_s = time.monotonic()
            recorder.signal(signal.SIGKILL)
            recorder.process.wait()
            publisher.stop()
            recover_bag(Path(response.bag_path))
            return Path(response.bag_path), publisher, started_s, killed_s, None
        time.sleep(clip_s)
        stopping_s, cpu1 = time.monotonic(), cpu_s(recorder.process.pid)
        assert call(node, stop, Trigger.Request()).success
        publisher.stop()
        return Path(response.bag_path), publisher, started_s, stopping_s, (cpu1 - cpu0) / (stopping_s - started_s)
    finally:
        if publisher is not None and publisher.running:
            publisher.stop()
        recorder.stop()


def kept_fraction(bag, publisher, start_s, end_s):
    content = read_with_rosbags(bag)
    published = set(publisher.between(start_s, end_s))
    return {topic: len(published & set(stamps)) / len(published) for topic, stamps in content.stamps.items()}


def offline_io(tmp):
    """ClipWriter throughput at the recorder's flushing (every 50 messages = 0.1 s at 500 Hz) and
    recover_bag time, for a 60 s clip (30,000 joint states)."""
    definitions = MessageDefinitions()
    spec = TopicSpec(JOINT_STATES, JOINT_STATE_TYPE, *definitions.definition(JOINT_STATE_TYPE))
    data = [joint_state_cdr(1_000_000_000 + i * 2_000_000) for i in range(30_000)]
    rows = []
    for storage in ('mcap', 'sqlite3'):
        clip = ClipWriter(tmp / f'io_{storage}', storage, {'label': 'bench'}, monotonic_s=lambda: 0.0)
        clip.open()
        clip.add_topic(spec)
        t0 = time.perf_counter()
        for i, raw in enumerate(data):
            clip.write(JOINT_STATES, i, raw)
            if i % 50 == 49:
                clip.flush()
        write_s = time.perf_counter() - t0
        crashed = shutil.copytree(clip.bag_dir, tmp / f'crashed_{storage}')
        clip.close()
        note = crashed / 'recording_in_progress.yaml'
        note.write_text(note.read_text().replace(f'pid: {os.getpid()}', 'pid: 0'))
        t0 = time.perf_counter()
        report = recover_bag(crashed)
        recover_s = time.perf_counter() - t0
        size_mb = sum(p.stat().st_size for p in clip.bag_dir.iterdir()) / 1e6
        rows.append((storage, len(data) / write_s, recover_s, sum(report.message_counts.values()), size_mb))
    return rows


def main():
    tmp = Path(tempfile.mkdtemp(prefix='bench_recorder_'))
    try:
        clips = []
        for storage in ('mcap', 'sqlite3'):
            bag, pub, t0, t1, cpu = record(tmp / storage, storage, clip_s=10.0)
            kept = kept_fraction(bag, pub, t0, t1)
            size_mb = sum(p.stat().st_size for p in bag.iterdir()) / 1e6
            clips.append(
                (storage, kept[JOINT_STATES], kept[WRENCH], len(pub.between(t0, t1)), cpu, size_mb / (t1 - t0) * 60.0)
            )
        kills = []
        for storage in ('mcap', 'mcap', 'sqlite3', 'sqlite3'):
            bag, pub, t0, killed_s, _ = record(tmp / f'kill_{len(kills)}', storage, 0.0, kill_at_s=3.0)
            recorded = set(read_with_rosbags(bag).stamps[JOINT_STATES])
            times = dict(pub.published)
            missing = [times[s] for s in pub.between(t0, killed_s) if s not in recorded]
            lost_window_s = killed_s - min(missing) if missing else 0.0
            kills.append(
                (
                    storage,
                    lost_window_s,
                    len(pub.between(t0, killed_s - 0.2)),
                    sum(1 for s in pub.between(t0, killed_s - 0.2) if s not in recorded),
                )
            )
        io_rows = offline_io(tmp)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)

    print('## Recorder: kept fraction at 500 Hz, cost, SIGKILL loss, bag I/O\n')
    print(
        '`ros2 run stylepong_recording recorder` (defaults: flush every 0.1 s, queue depth 1000, reliable QoS) '
        f'recording `/joint_states` and `{WRENCH}`, both published at 500 Hz (reliable, depth 10) by '
        'a Python thread in the benchmark process; clips started and stopped through the services. '
        'Kept = share of the messages published between the start answer and the stop call found in '
        'the bag (read back with rosbags AnyReader); CPU = recorder process CPU time / clip time.\n'
    )
    print(
        '| storage | clip | joint states published | kept /joint_states | kept wrench '
        '| recorder CPU (one core) | bag MB per minute |'
    )
    print('|---|---|---|---|---|---|---|')
    for storage, kept_js, kept_w, n, cpu, mb_min in clips:
        print(f'| {storage} | 10 s | {n} | {kept_js:.4f} | {kept_w:.4f} | {cpu * 100:.0f} % | {mb_min:.1f} |')
    print(
        '\nSIGKILL 3 s into a clip, then `recover_bag`: lost window = kill time minus the publish time of '
        'the oldest joint state missing from the recovered bag (0 = nothing lost).\n'
    )
    print('| storage | lost window | joint states published up to 0.2 s before the kill | of those missing |')
    print('|---|---|---|---|')
    for storage, window_s, n, missing in kills:
        print(f'| {storage} | {window_s * 1000:.0f} ms | {n} | {missing} |')
    print(
        '\nOffline, one process: ClipWriter writing 30,000 JointState (a 60 s clip at 500 Hz) with a flush '
        'every 50 messages, then `recover_bag` on a copy taken before close (no metadata, no footer).\n'
    )
    print('| storage | write rate | recover_bag time (60 s clip) | messages recovered | bag size |')
    print('|---|---|---|---|---|')
    for storage, rate, recover_s, count, size_mb in io_rows:
        print(f'| {storage} | {rate / 1000:.0f}k msg/s | {recover_s:.2f} s | {count} | {size_mb:.1f} MB |')


if __name__ == '__main__':
    main()
