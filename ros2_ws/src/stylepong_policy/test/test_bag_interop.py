"""build_dataset on real rosbag2 recordings (../shared/interop-bags; skipped when absent).

The expected values come from rosbags' own AnyReader and deserializer, not from the code under test.
"""

import os
import pathlib

import numpy as np
import pytest

from stylepong_policy.training.build_dataset import build_parser, process_bag, settings_from_args
from stylepong_recording.joint_state_bags import URDF_JOINTS, read_with_rosbags

# ../shared/interop-bags beside the repository, unless STYLEPONG_INTEROP_BAGS names another copy.
INTEROP = pathlib.Path(
    os.environ.get('STYLEPONG_INTEROP_BAGS')
    or pathlib.Path(__file__).resolve().parents[4].parent / 'shared' / 'interop-bags'
)
UR3E = ('ur3e-hw-sqlite3-v5-toolpath', 'ur3e-ursim-sqlite3-v5-toolpath', 'ur3e-hw-sqlite3-v5-pos1')

pytestmark = pytest.mark.skipif(not INTEROP.is_dir(), reason=f'{INTEROP} is absent')


def run_bag(bag: pathlib.Path, *extra: str):
    args = build_parser().parse_args([str(bag), '-o', 'unused.npz', *extra])
    args.joints = args.joints or URDF_JOINTS
    return process_bag(bag, settings_from_args(args))


@pytest.mark.parametrize('name', UR3E)
def test_ur3e_recordings_give_clips_equal_to_the_raw_data(name):
    bag = INTEROP / name
    # pos1 is a static recording: with trimming it rightly gives no clip, so compare it untrimmed.
    report = run_bag(bag, *(['--idle-speed-rad-s', '0'] if name.endswith('pos1') else []))
    assert report.used, report.reason
    assert not report.problems
    stamps, positions, velocities = read_with_rosbags(bag)
    (clip,) = report.clips
    assert clip.time_source == 'header' and clip.velocity_source == 'bag'
    assert np.allclose(np.diff(clip.t), 1 / 60, rtol=0, atol=1e-5)
    assert stamps[0] / 1e9 - 1e-6 <= clip.t[0] and clip.t[-1] <= stamps[-1] / 1e9 + 1e-6
    # Interpolate the raw samples at the clip's times, relative to the first stamp (float precision).
    t_rel = (stamps - stamps[0]) / 1e9
    clip_rel = clip.t - stamps[0] / 1e9
    for j in range(6):
        assert np.abs(clip.q[:, j] - np.interp(clip_rel, t_rel, positions[:, j])).max() < 1e-3
        assert np.abs(clip.qd[:, j] - np.interp(clip_rel, t_rel, velocities[:, j])).max() < 1e-3
    # The UR driver reports joints unwrapped (wrist_3 near -12.2 rad in pos1): kept as they are.
    assert np.abs(clip.q[0] - positions[np.searchsorted(t_rel, clip_rel[0])]).max() < 0.01


def test_every_interop_bag_is_read_or_rejected_with_a_one_line_reason():
    bags = sorted(p for p in INTEROP.iterdir() if p.is_dir())
    assert len(bags) >= 18
    reports = {bag.name: run_bag(bag) for bag in bags}
    for name, report in reports.items():
        if report.used:
            assert report.clips
        else:
            assert report.reason and '\n' not in report.reason and len(report.reason) < 400, name
    assert {name for name, r in reports.items() if r.used} == {
        'ur3e-hw-sqlite3-v5-toolpath',
        'ur3e-ursim-sqlite3-v5-toolpath',
    }
    reasons = {name: r.reason for name, r in reports.items()}
    assert 'not supported' in reasons['rosbag2-sqlite3-v4-wrong_serialization_format']
    assert 'no sensor_msgs/msg/JointState topic' in reasons['rosbag2-mcap-v8-service_events']
    assert 'idle throughout' in reasons['ur3e-hw-sqlite3-v5-pos1']
    assert '--topic' in reasons['ats-mcap-v9-jazzy-jointstate']


def test_other_robots_joint_states_by_topic_joints_and_assume_order():
    """The aerial-manipulator bags: 3-joint arms, topic choice, nameless messages, custom px4 types."""
    report = run_bag(INTEROP / 'ats-mcap-v9-jazzy-jointstate', '--topic', '/servo/out/state', '--joints', 'q0,q1,q2')
    assert report.used and not report.problems and report.clips[0].q.shape[1] == 3
    nameless = INTEROP / 'ats-sqlite3-v5-jointstate-noname'
    report = run_bag(nameless, '--topic', '/servo/out/state', '--joints', 'a,b,c')
    assert not report.used and '--assume-order' in report.reason
    report = run_bag(
        nameless, '--topic', '/servo/out/state', '--joints', 'a,b,c', '--assume-order', '--idle-speed-rad-s', '0'
    )
    assert report.used and not report.problems
    # Thousands of px4 messages there cannot be deserialized; the JointState topic is unaffected.
    report = run_bag(
        INTEROP / 'ats-sqlite3-v5-jointstate-px4', '--topic', '/controller/out/servo_positions', '--joints', 'q1,q2,q3'
    )
    assert report.used and not report.problems
