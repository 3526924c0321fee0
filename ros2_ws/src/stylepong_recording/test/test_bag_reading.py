"""Reading JointState out of rosbag2 bags of every kind (stylepong_recording.bag_reading)."""

import shutil

import numpy as np
import pytest

from stylepong_recording.bag_errors import BagError
from stylepong_recording.bag_reading import read_joint_states
from stylepong_recording.bag_search import find_bags
from stylepong_recording.clip_writer import TopicSpec, open_clip
from stylepong_recording.joint_state_bags import (
    DRIVER_JOINTS,
    EPOCH_NS,
    URDF_JOINTS,
    Swing,
    jazzy_typestore,
    joint_state_cdr,
    truncate_file,
    wrap_to_pi,
    write_driver_bag,
    write_raw_bag,
    write_recorder_bag,
)
from stylepong_recording.joint_state_cdr import JointStateCdrReader
from stylepong_recording.msg_definitions import MessageDefinitions
from stylepong_recording.recover_bag import recover_bag

STORE = jazzy_typestore()
SWING = Swing(rest_before_s=0.1, duration_s=0.4, rest_after_s=0.1)


def random_message(rng):
    n_names = int(rng.integers(0, 9))
    names = [''.join(rng.choice(list('abcxyz_'), size=int(rng.integers(0, 12)))) for _ in range(n_names)]
    n_pos = int(rng.choice([0, n_names, 3]))
    n_vel = int(rng.choice([0, n_pos, 1]))
    stamp = int(rng.integers(0, 2**31 - 1)) * 1_000_000_000 + int(rng.integers(0, 999_999_999))
    frame_id = 'f' * int(rng.integers(0, 10))
    return (
        stamp,
        names,
        rng.normal(size=n_pos),
        rng.normal(size=n_vel),
        rng.normal(size=int(rng.integers(0, 4))),
        frame_id,
    )


def test_fast_reader_equals_rosbags_deserializer_on_random_messages():
    rng = np.random.default_rng(1)
    reader = JointStateCdrReader()
    for _ in range(400):
        stamp, names, pos, vel, eff, frame_id = random_message(rng)
        raw = joint_state_cdr(STORE, stamp, names, pos, vel, eff, frame_id=frame_id)
        reference = STORE.deserialize_cdr(raw, 'sensor_msgs/msg/JointState')
        got_stamp, name_id, got_pos, got_vel = reader.read(raw)
        assert got_stamp == reference.header.stamp.sec * 1_000_000_000 + reference.header.stamp.nanosec
        assert reader.name_lists[name_id] == tuple(reference.name)
        assert np.array_equal(got_pos, reference.position) and np.array_equal(got_vel, reference.velocity)


def test_batch_reader_takes_only_messages_with_the_template_layout():
    reader = JointStateCdrReader()
    raws = [
        joint_state_cdr(STORE, EPOCH_NS + i, URDF_JOINTS, np.full(6, i), np.full(6, -i), frame_id='base')
        for i in range(20)
    ]
    raws[5] = joint_state_cdr(STORE, EPOCH_NS + 5, URDF_JOINTS, np.full(6, 5.0), frame_id='base')  # no velocity
    raws[7] = joint_state_cdr(STORE, EPOCH_NS + 7, URDF_JOINTS, np.full(6, 7.0), np.ones(6), frame_id='bose')
    layout, rows, stamps, pos, vel = reader.read_batch(raws, raws[0])
    assert 5 not in rows and 7 in rows  # frame_id's characters do not decide any offset
    assert np.array_equal(stamps, EPOCH_NS + rows)
    assert np.array_equal(pos[:, 0], rows.astype(float)) and pos.shape == (len(rows), 6) and vel.shape[1] == 6


@pytest.mark.parametrize(
    'storage,compression',
    [('mcap', None), ('sqlite3', None), ('sqlite3', 'message'), ('sqlite3', 'file'), ('mcap', 'file')],
)
def test_recorder_bags_read_back_exactly(tmp_path, storage, compression):
    bag = tmp_path / 'forward_20251121_101112_123'
    count = write_recorder_bag(bag, SWING, SWING.total_s, storage=storage, compression=compression)
    recording = read_joint_states(bag, joints=URDF_JOINTS)
    assert recording.message_count == count and not recording.problems
    assert recording.label == 'forward' and recording.topic == '/joint_states'
    t_s = (recording.header_stamp_ns - EPOCH_NS) / 1e9
    q, qd = SWING(t_s)
    assert np.abs(recording.position_rad - q).max() < 1e-12
    assert np.abs(recording.velocity_rad_s - qd).max() < 1e-12


def test_driver_order_gripper_and_empty_velocities(tmp_path):
    bag = tmp_path / 'take'
    truth = write_driver_bag(bag, SWING, SWING.total_s)
    recording = read_joint_states(bag, joints=URDF_JOINTS)
    assert not recording.problems and recording.label == 'forward'
    assert np.array_equal(recording.header_stamp_ns, truth.stamps_ns)
    assert np.array_equal(recording.receive_time_ns, truth.receive_ns)
    expected = truth.q_true.copy()
    expected[:, 5] = wrap_to_pi(expected[:, 5])  # as recorded; continuity is the dataset's job
    assert np.abs(recording.position_rad - expected).max() < 1e-12
    assert np.isnan(recording.velocity_rad_s).all()
    # Joints can be asked for in any order, including the driver's.
    as_driver = read_joint_states(bag, joints=DRIVER_JOINTS)
    assert np.array_equal(as_driver.position_rad[:, -1], recording.position_rad[:, 0])


def test_metadata_qos_that_differs_from_the_storage_is_reported_and_read_past(tmp_path):
    bag = tmp_path / 'take'
    truth = write_driver_bag(bag, SWING, SWING.total_s, qos_in_mcap=False)
    recording = read_joint_states(bag, joints=URDF_JOINTS)
    (problem,) = recording.problems
    assert f'yielded 0 of the {len(truth.stamps_ns)}' in problem and 'storage directly' in problem
    assert recording.message_count == len(truth.stamps_ns)


def test_big_endian_messages_go_through_the_generic_decoder(tmp_path):
    stamps = EPOCH_NS + np.arange(50) * 2_000_000
    messages = [
        (s, joint_state_cdr(STORE, s, URDF_JOINTS, np.full(6, i * 0.01), little_endian=(i % 2 == 0)))
        for i, s in enumerate(stamps)
    ]
    write_raw_bag(tmp_path / 'bag', {'/joint_states': messages})
    recording = read_joint_states(tmp_path / 'bag', joints=URDF_JOINTS)
    assert not recording.problems
    assert np.allclose(recording.position_rad[:, 0], np.arange(50) * 0.01)


def test_undecodable_messages_are_counted_and_the_rest_kept(tmp_path):
    bag = tmp_path / 'bag'
    bad = {10, 11, 200}
    count = write_recorder_bag(
        bag, SWING, SWING.total_s, storage='sqlite3', raw_messages=lambda i, raw: raw[:30] if i in bad else raw
    )
    recording = read_joint_states(bag, joints=URDF_JOINTS)
    assert recording.message_count == count - len(bad)
    (problem,) = recording.problems
    assert f'3 of {count} messages could not be decoded' in problem and str(bag) in problem


def test_nan_positions_are_dropped_and_reported(tmp_path):
    stamps = EPOCH_NS + np.arange(20) * 2_000_000
    messages = [
        (s, joint_state_cdr(STORE, s, URDF_JOINTS, np.full(6, np.nan if i == 4 else 0.1))) for i, s in enumerate(stamps)
    ]
    write_raw_bag(tmp_path / 'bag', {'/joint_states': messages})
    recording = read_joint_states(tmp_path / 'bag', joints=URDF_JOINTS)
    assert recording.message_count == 19 and any('NaN' in p for p in recording.problems)


def test_empty_names_need_assume_order(tmp_path):
    stamps = EPOCH_NS + np.arange(20) * 2_000_000
    messages = [(s, joint_state_cdr(STORE, s, [], np.arange(6) + i)) for i, s in enumerate(stamps)]
    write_raw_bag(tmp_path / 'bag', {'/joint_states': messages})
    with pytest.raises(BagError, match='--assume-order'):
        read_joint_states(tmp_path / 'bag', joints=URDF_JOINTS)
    recording = read_joint_states(tmp_path / 'bag', joints=URDF_JOINTS, assume_order=True)
    assert np.array_equal(recording.position_rad[3], np.arange(6) + 3.0)


def test_messages_without_the_requested_joints_are_ignored(tmp_path):
    stamps = EPOCH_NS + np.arange(40) * 2_000_000
    messages = [
        (
            s,
            joint_state_cdr(STORE, s, ['gripper'], [0.2])
            if i % 2
            else joint_state_cdr(STORE, s, URDF_JOINTS, np.full(6, i)),
        )
        for i, s in enumerate(stamps)
    ]
    write_raw_bag(tmp_path / 'bag', {'/joint_states': messages})
    recording = read_joint_states(tmp_path / 'bag', joints=URDF_JOINTS)
    assert recording.message_count == 20 and any('gripper' in n for n in recording.notes)
    with pytest.raises(BagError, match='no message carries all of the joints'):
        read_joint_states(tmp_path / 'bag', joints=('elbow_joint', 'missing_joint'))


def test_a_drivers_tf_prefix_on_the_joint_names_is_read_past_and_noted(tmp_path):
    stamps = EPOCH_NS + np.arange(20) * 8_000_000
    prefixed = ['ur5_' + j for j in reversed(URDF_JOINTS)] + ['ur5_gripper_joint']
    messages = [
        (s, joint_state_cdr(STORE, s, prefixed, [*np.arange(6.0)[::-1] + i, 0.5])) for i, s in enumerate(stamps)
    ]
    write_raw_bag(tmp_path / 'bag', {'/joint_states': messages})
    recording = read_joint_states(tmp_path / 'bag', joints=URDF_JOINTS)
    assert np.array_equal(recording.position_rad, np.arange(6.0) + np.arange(20)[:, None])
    assert recording.notes == ["/joint_states: joints named with the prefix 'ur5_' (a driver's tf_prefix)"]

    # Two arms in one message: no telling which is meant.
    two_arms = [('left_' + j) for j in URDF_JOINTS] + [('right_' + j) for j in URDF_JOINTS]
    write_raw_bag(
        tmp_path / 'two', {'/joint_states': [(s, joint_state_cdr(STORE, s, two_arms, np.zeros(12))) for s in stamps]}
    )
    with pytest.raises(BagError, match='no message carries all of the joints'):
        read_joint_states(tmp_path / 'two', joints=URDF_JOINTS)


def test_topic_choice(tmp_path):
    stamps = EPOCH_NS + np.arange(5) * 2_000_000
    js = [(s, joint_state_cdr(STORE, s, URDF_JOINTS, np.zeros(6))) for s in stamps]
    text = [
        (s, bytes(STORE.serialize_cdr(STORE.types['std_msgs/msg/String'](data='x'), 'std_msgs/msg/String')))
        for s in stamps
    ]
    write_raw_bag(
        tmp_path / 'bag',
        {'/a/joint_states': js, '/b/joint_states': js[:2], '/chatter': text},
        msgtypes={'/chatter': 'std_msgs/msg/String'},
    )
    with pytest.raises(BagError, match='several JointState topics.*--topic'):
        read_joint_states(tmp_path / 'bag', joints=URDF_JOINTS)
    assert read_joint_states(tmp_path / 'bag', joints=URDF_JOINTS, topic='/b/joint_states').message_count == 2
    with pytest.raises(BagError, match='not sensor_msgs/msg/JointState'):
        read_joint_states(tmp_path / 'bag', joints=URDF_JOINTS, topic='/chatter')
    with pytest.raises(BagError, match='no topic /nope'):
        read_joint_states(tmp_path / 'bag', joints=URDF_JOINTS, topic='/nope')


def test_broken_storage_is_named_in_one_line(tmp_path):
    truncated = tmp_path / 'truncated'
    write_recorder_bag(truncated, SWING, SWING.total_s)
    (mcap,) = truncated.glob('*.mcap')
    truncate_file(mcap)
    with pytest.raises(BagError, match='truncated mcap') as error:
        read_joint_states(truncated, joints=URDF_JOINTS)
    assert str(mcap) in str(error.value) and '\n' not in str(error.value)

    missing = tmp_path / 'missing'
    write_recorder_bag(missing, SWING, SWING.total_s, storage='sqlite3')
    (db3,) = missing.glob('*.db3')
    db3.unlink()
    with pytest.raises(BagError, match='missing'):
        read_joint_states(missing, joints=URDF_JOINTS)

    garbage = tmp_path / 'garbage'
    write_recorder_bag(garbage, SWING, SWING.total_s, storage='sqlite3')
    (db3,) = garbage.glob('*.db3')
    db3.write_bytes(b'not a database' * 100)
    with pytest.raises(BagError, match='not an sqlite3'):
        read_joint_states(garbage, joints=URDF_JOINTS)

    bad_yaml = tmp_path / 'bad_yaml'
    write_recorder_bag(bad_yaml, SWING, SWING.total_s)
    (bad_yaml / 'metadata.yaml').write_text('rosbag2_bagfile_information: [unclosed')
    with pytest.raises(BagError, match='metadata.yaml'):
        read_joint_states(bad_yaml, joints=URDF_JOINTS)


def test_a_recording_killed_before_closing_is_named_with_the_way_out(tmp_path):
    bag = tmp_path / 'forward_20251121_101112_123'
    write_recorder_bag(bag, SWING, SWING.total_s)
    (bag / 'metadata.yaml').unlink()
    (mcap,) = bag.glob('*.mcap')
    truncate_file(mcap)
    with pytest.raises(BagError, match='truncated mcap.*recover_bag'):
        read_joint_states(bag, joints=URDF_JOINTS)
    (bag / 'recording_in_progress.yaml').write_text('label: forward\n')
    with pytest.raises(BagError, match='in progress.*recover_bag'):
        read_joint_states(bag, joints=URDF_JOINTS)


def test_storage_files_without_metadata_are_read_directly(tmp_path):
    bag = tmp_path / 'forward_20251121_101112_123'
    count = write_recorder_bag(bag, SWING, SWING.total_s)
    (bag / 'metadata.yaml').unlink()
    recording = read_joint_states(bag, joints=URDF_JOINTS)
    assert recording.message_count == count and any('no metadata.yaml' in n for n in recording.notes)
    (mcap,) = bag.glob('*.mcap')
    assert read_joint_states(mcap, joints=URDF_JOINTS).message_count == count


def test_find_bags_searches_parents_and_reports_what_holds_none(tmp_path):
    for name in ('a/forward_1', 'a/deeper/leftward_2', 'b/rightward_3'):
        write_recorder_bag(tmp_path / name, SWING, SWING.total_s, storage='sqlite3')
    (tmp_path / 'empty').mkdir()
    (tmp_path / 'notes.txt').write_text('x')
    search = find_bags(
        [
            tmp_path / 'a',
            tmp_path / 'b' / 'rightward_3',
            tmp_path / 'b' / 'rightward_3' / 'metadata.yaml',
            tmp_path / 'empty',
            tmp_path / 'nope',
            tmp_path / 'notes.txt',
        ]
    )
    assert [b.name for b in search.bags] == ['leftward_2', 'forward_1', 'rightward_3']
    assert {p.name: r for p, r in search.rejected}.keys() == {'empty', 'nope', 'notes.txt'}
    shutil.rmtree(tmp_path / 'a')
    assert [b.name for b in find_bags([tmp_path]).bags] == ['rightward_3']


def test_a_non_standard_joint_state_definition_is_decoded_with_the_bags_own(tmp_path):
    """A bag whose JointState differs (float32 velocities): the fast reader must not guess its layout."""
    from rosbags.rosbag2 import Writer
    from rosbags.rosbag2.enums import StoragePlugin
    from rosbags.typesys import Stores, get_types_from_msg, get_typestore

    from stylepong_recording.joint_state_bags import JOINT_STATE_MSGDEF

    msgdef = JOINT_STATE_MSGDEF.replace('float64[] velocity', 'float32[] velocity')
    custom = get_typestore(Stores.EMPTY)
    custom.register(get_types_from_msg(msgdef, 'sensor_msgs/msg/JointState'))
    types = custom.types
    with Writer(tmp_path / 'bag', version=9, storage_plugin=StoragePlugin.MCAP) as writer:
        connection = writer.add_connection(
            '/joint_states',
            'sensor_msgs/msg/JointState',
            msgdef=msgdef,
            rihs01=custom.hash_rihs01('sensor_msgs/msg/JointState'),
        )
        for i in range(10):
            message = types['sensor_msgs/msg/JointState'](
                header=types['std_msgs/msg/Header'](
                    stamp=types['builtin_interfaces/msg/Time'](sec=1000 + i, nanosec=0), frame_id=''
                ),
                name=list(URDF_JOINTS),
                position=np.full(6, 0.5 * i),
                velocity=np.full(6, i, dtype=np.float32),
                effort=np.zeros(0),
            )
            writer.write(
                connection, (1000 + i) * 10**9, bytes(custom.serialize_cdr(message, 'sensor_msgs/msg/JointState'))
            )
    recording = read_joint_states(tmp_path / 'bag', joints=URDF_JOINTS)
    assert not recording.problems and any('differs from the standard' in n for n in recording.notes)
    assert np.array_equal(recording.position_rad[:, 2], 0.5 * np.arange(10))
    assert np.array_equal(recording.velocity_rad_s[:, 2], np.arange(10.0))


def write_clip(output_dir, storage, killed=False):
    """50 joint states through the recorder's ClipWriter, closed, or left as a killed recorder leaves them."""
    definitions = MessageDefinitions(find_msg_file=lambda msgtype: None)
    msgtype = 'sensor_msgs/msg/JointState'
    spec = TopicSpec('/joint_states', msgtype, *definitions.definition(msgtype))
    clip = open_clip(output_dir, 'leftward', storage, [spec])
    for i in range(1, 51):
        clip.write('/joint_states', EPOCH_NS + i, joint_state_cdr(STORE, EPOCH_NS + i, URDF_JOINTS, [i * 1e-3] * 6))
    if killed:
        clip.flush()
        clip.abort()
    else:
        clip.close()
    return clip.bag_dir


@pytest.mark.parametrize('storage', ['mcap', 'sqlite3'])
@pytest.mark.parametrize('killed', [False, True])
def test_a_clip_the_recorder_writes_or_recover_bag_rebuilds_reads_back_with_its_label(tmp_path, storage, killed):
    """The writer, recover_bag and this reader share stylepong_recording.bag_layout: the label one writes
    is the label the other finds, in a closed clip and in one rebuilt after its recorder died."""
    bag = write_clip(tmp_path / 'bags', storage, killed)
    if killed:
        with pytest.raises(BagError, match='in progress.*stylepong_recording recover_bag'):
            read_joint_states(bag, joints=URDF_JOINTS)
        # force: the recording note names this test's own process, which is still alive.
        assert recover_bag(bag, force=True).outcome == 'recovered'
    recording = read_joint_states(bag, joints=URDF_JOINTS)
    assert recording.label == 'leftward' and recording.storage == storage and not recording.problems
    assert np.array_equal(recording.position_rad[:, 0], np.arange(1, 51) * 1e-3)
