"""ClipWriter: labelled rosbag2 clips through rosbags, flushed often, clear errors (no ROS graph)."""

import datetime
import errno

import pytest
from offline_clips import open_writer, topic_spec  # beside this file: conftest.py

from stylepong_recording.bag_check import (
    JOINT_NAMES,
    JOINT_STATE_TYPE,
    JOINT_STATES,
    WRENCH,
    WRENCH_TYPE,
    joint_state_cdr,
    read_with_mcap_ros2,
    read_with_rosbags,
    read_with_sqlite3,
    storage_file,
)
from stylepong_recording.bag_layout import IN_PROGRESS_NAME
from stylepong_recording.clip_writer import (
    ClipError,
    bag_dir_name,
    label_from_bag_dir_name,
    label_problem,
    open_clip,
)
from stylepong_recording.msg_definitions import MessageDefinitions, UnknownMessageType


@pytest.mark.parametrize('label', ['forward', 'leftward', 'fore_hand-2', 'v1.2', 'A' * 64])
def test_safe_labels_are_accepted(label):
    assert label_problem(label) is None


@pytest.mark.parametrize(
    'label, why',
    [
        ('', 'empty'),
        ('a/b', 'separator'),
        ('../up', 'separator'),
        ('a\\b', 'separator'),
        ('..', 'separator'),
        ('.hidden', 'starts with'),
        ('-x', 'starts with'),
        ('with space', 'characters'),
        ('tab\there', 'characters'),
        ('nul\0', 'characters'),
        ('A' * 65, 'longer than'),
    ],
)
def test_unsafe_labels_are_refused_with_the_reason(label, why):
    assert why in label_problem(label)


def test_bag_dir_name_carries_label_and_time_and_gives_the_label_back():
    when = datetime.datetime(2025, 3, 4, 5, 6, 7, 89_000)
    name = bag_dir_name('fore_hand', when)
    assert name == 'fore_hand_20250304_050607_089'
    assert label_from_bag_dir_name(name) == 'fore_hand'
    assert label_from_bag_dir_name('rosbag2_2025_03_04-05_06_07') is None


@pytest.mark.parametrize('storage', ['mcap', 'sqlite3'])
def test_clip_reads_back_with_every_message_its_log_times_and_label(tmp_path, storage):
    topics = [topic_spec(JOINT_STATES, JOINT_STATE_TYPE), topic_spec(WRENCH, WRENCH_TYPE)]
    when = datetime.datetime(2025, 1, 2, 3, 4, 5)
    clip = open_clip(tmp_path / 'bags', 'forward', storage, topics, now=when)
    assert clip.bag_dir == tmp_path / 'bags' / 'forward_20250102_030405_000'
    assert (clip.bag_dir / IN_PROGRESS_NAME).is_file()
    stamps = [1_700_000_000_000_000_000 + i * 2_000_000 for i in range(1500)]
    for i, stamp in enumerate(stamps):
        clip.write(JOINT_STATES, stamp + 300_000, joint_state_cdr(stamp))
    summary = clip.close()

    assert summary.message_counts == {JOINT_STATES: 1500, WRENCH: 0}
    assert summary.duration_s == pytest.approx(1499 * 0.002)
    suffix = {'mcap': '.mcap', 'sqlite3': '.db3'}[storage]
    assert sorted(p.name for p in clip.bag_dir.iterdir()) == ['forward_20250102_030405_000' + suffix, 'metadata.yaml']
    content = read_with_rosbags(clip.bag_dir)
    assert content.custom_data == {'label': 'forward'}
    assert content.stamps[JOINT_STATES] == stamps
    assert content.log_times[JOINT_STATES] == [s + 300_000 for s in stamps]
    assert content.metadata_counts == {JOINT_STATES: 1500, WRENCH: 0}
    if storage == 'mcap':
        mcap = read_with_mcap_ros2(storage_file(clip.bag_dir, '.mcap'))
        assert mcap.stamps[JOINT_STATES] == stamps
        assert mcap.metadata_counts[JOINT_STATES] == 1500
        assert 'rosbag2' in mcap.custom_data
    else:  # the .db3 file through Python's sqlite3 and a CDR decoder of its own
        sql, joint_states = read_with_sqlite3(storage_file(clip.bag_dir, '.db3'))
        assert sql.custom_data == {'label': 'forward'}
        assert sql.stamps == {JOINT_STATES: stamps, WRENCH: []}
        assert sql.log_times[JOINT_STATES] == [s + 300_000 for s in stamps]
        assert sql.metadata_counts == {JOINT_STATES: 1500, WRENCH: 0}
        assert all(js.name == list(JOINT_NAMES) and js.position == [js.stamp_ns * 1e-9] * 6 for js in joint_states)


def test_topics_can_join_a_running_clip(tmp_path):
    clip = open_clip(tmp_path, 'forward', 'mcap', [topic_spec(JOINT_STATES, JOINT_STATE_TYPE)])
    clip.write(JOINT_STATES, 10, joint_state_cdr(1))
    clip.add_topic(topic_spec(WRENCH, WRENCH_TYPE))
    clip.add_topic(topic_spec(WRENCH, WRENCH_TYPE))  # idempotent
    clip.write(JOINT_STATES, 20, joint_state_cdr(2))
    assert clip.close().message_counts == {JOINT_STATES: 2, WRENCH: 0}
    assert read_with_rosbags(clip.bag_dir).stamps == {JOINT_STATES: [1, 2], WRENCH: []}


def test_flush_happens_once_per_period_while_writing(tmp_path):
    clip, clock = open_writer(tmp_path / 'clip', topics=[(JOINT_STATES, JOINT_STATE_TYPE)])
    size = clip.storage_path.stat().st_size
    clip.write(JOINT_STATES, 1, joint_state_cdr(1))
    clock.now_s = 0.09
    clip.write(JOINT_STATES, 2, joint_state_cdr(2))
    assert clip.storage_path.stat().st_size == size  # still in memory
    clock.now_s = 0.1
    clip.write(JOINT_STATES, 3, joint_state_cdr(3))
    assert clip.storage_path.stat().st_size > size  # period over: all three went to the OS
    size = clip.storage_path.stat().st_size
    clip.write(JOINT_STATES, 4, joint_state_cdr(4))
    clip.flush_if_due()
    assert clip.storage_path.stat().st_size == size
    clock.now_s = 0.25
    clip.flush_if_due()  # the node's timer, when no message comes
    assert clip.storage_path.stat().st_size > size
    clip.close()
    assert read_with_rosbags(clip.bag_dir).stamps[JOINT_STATES] == [1, 2, 3, 4]


def test_open_refuses_an_unusable_output_dir(tmp_path):
    blocker = tmp_path / 'a_file'
    blocker.write_text('not a directory')
    with pytest.raises(ClipError, match='output_dir .* cannot be created'):
        open_clip(blocker / 'bags', 'forward', 'mcap', [])
    with pytest.raises(ClipError, match='output_dir .* is not a directory'):
        open_clip(blocker, 'forward', 'mcap', [])


def test_open_refuses_when_the_disk_is_too_full(tmp_path):
    with pytest.raises(ClipError, match='disk full: only .* MB free'):
        open_clip(tmp_path, 'forward', 'mcap', [], min_free_space_mb=1e12)
    assert list(tmp_path.iterdir()) == []


def test_open_refuses_bad_label_storage_and_existing_bag(tmp_path):
    with pytest.raises(ClipError, match='path separator'):
        open_clip(tmp_path, '../evil', 'mcap', [])
    with pytest.raises(ClipError, match='unknown storage'):
        open_clip(tmp_path, 'forward', 'rosbag1', [])
    when = datetime.datetime(2025, 1, 1)
    open_clip(tmp_path, 'forward', 'mcap', [], now=when).close()
    with pytest.raises(ClipError, match='exists already'):
        open_clip(tmp_path, 'forward', 'mcap', [], now=when)
    assert list(tmp_path.iterdir()) == [tmp_path / bag_dir_name('forward', when)]


@pytest.mark.parametrize('storage', ['mcap', 'sqlite3'])
def test_a_full_disk_while_writing_stops_the_clip_with_the_reason(tmp_path, storage, monkeypatch):
    clip, clock = open_writer(tmp_path / 'clip', storage, topics=[(JOINT_STATES, JOINT_STATE_TYPE)])
    clip.write(JOINT_STATES, 1, joint_state_cdr(1))

    def no_space():
        raise OSError(errno.ENOSPC, 'No space left on device')

    monkeypatch.setattr(clip._writer.storage, 'flush', no_space)
    clock.now_s = 1.0
    with pytest.raises(ClipError, match='disk full') as failure:
        clip.write(JOINT_STATES, 2, joint_state_cdr(2))
    assert 'recover_bag' in str(failure.value)
    assert not clip.is_open
    with pytest.raises(ClipError, match='not open'):
        clip.write(JOINT_STATES, 3, joint_state_cdr(3))


def test_definitions_of_installed_custom_types_come_from_their_msg_files(tmp_path):
    (tmp_path / 'Pair.msg').write_text('std_msgs/Header header\nInner[2] inner\n')
    (tmp_path / 'Inner.msg').write_text('float64 value\n')
    files = {'demo_msgs/msg/Pair': tmp_path / 'Pair.msg', 'demo_msgs/msg/Inner': tmp_path / 'Inner.msg'}
    definitions = MessageDefinitions(find_msg_file=files.get)
    msgdef, rihs01 = definitions.definition('demo_msgs/msg/Pair')
    assert 'MSG: demo_msgs/Inner' in msgdef and 'MSG: std_msgs/Header' in msgdef
    assert rihs01.startswith('RIHS01_')
    with pytest.raises(UnknownMessageType, match='no definition of demo_msgs/msg/Missing'):
        definitions.definition('demo_msgs/msg/Missing')
