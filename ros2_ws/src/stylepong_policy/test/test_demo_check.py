"""demo_check: good demonstrations pass, each kind of bad one is refused with one line naming its bag."""

import pathlib
import shutil
import subprocess
import sys
import time

import numpy as np
import pytest

from stylepong_policy.training import build_dataset
from stylepong_policy.training.dataset import ReferenceDataset
from stylepong_policy.training.demo_check import (
    MIN_RATE_HZ,
    DemonstrationError,
    check_demonstrations,
    frames_after_speedup,
)
from stylepong_recording.joint_state_bags import (
    EPOCH_NS,
    Swing,
    jazzy_typestore,
    joint_state_cdr,
    truncate_file,
    write_driver_bag,
    write_raw_bag,
    write_recorder_bag,
)

SHIPPED_BAGS = pathlib.Path(__file__).resolve().parents[3] / 'bags'
WINDOW = 8  # the recipe's discriminator window (config/amp.yaml sequence_length)
SWING = Swing()


def refusal(path, window_frames: int = WINDOW) -> str:
    with pytest.raises(DemonstrationError) as caught:
        check_demonstrations(path, window_frames=window_frames)
    return str(caught.value)


def assert_one_line_naming(message: str, bag: pathlib.Path, *words: str) -> None:
    assert '\n' not in message, message
    assert message.startswith(f'{bag}: '), message
    for word in words:
        assert word in message, message


@pytest.fixture
def good_folder(tmp_path):
    """A folder with one good recorder bag per label (500 Hz, mcap)."""
    folder = tmp_path / 'demos'
    for label in ('forward', 'leftward', 'rightward'):
        write_recorder_bag(folder / f'{label}_20250101_120000_000', SWING, SWING.total_s, label=label)
    return folder


def test_the_shipped_clips_pass_with_every_label():
    started = time.perf_counter()
    found = check_demonstrations(SHIPPED_BAGS, window_frames=WINDOW)
    elapsed_s = time.perf_counter() - started
    assert found.kind == 'bags' and len(found.bags) == 7
    assert found.clips_per_label() == {'forward': 3, 'leftward': 2, 'rightward': 2}
    assert found.labels_missing == ()
    assert all(b.rate_hz == pytest.approx(500.0) for b in found.bags)
    assert elapsed_s < 10.0, f'checking 7 bags took {elapsed_s:.1f} s'


def test_the_set_is_the_dataset_build_dataset_writes(tmp_path):
    found = check_demonstrations(SHIPPED_BAGS, window_frames=WINDOW)
    ours = found.reference_dataset()
    assert build_dataset.run([str(SHIPPED_BAGS), '-o', str(tmp_path / 'built.npz')]) == 0
    built = ReferenceDataset.load(tmp_path / 'built.npz')
    assert ours.num_clips == built.num_clips == 28
    for key in ('t', 'q', 'qd', 'clip_start', 'clip_length', 'speed_factor', 'label', 'source', 'original'):
        assert np.array_equal(getattr(ours, key), getattr(built, key)), key
    assert ours.joint_names == built.joint_names


def test_a_set_with_only_forward_clips_passes_and_says_which_labels_it_lacks(tmp_path):
    folder = tmp_path / 'only_forward'
    for bag in sorted(SHIPPED_BAGS.glob('forward_*')):
        shutil.copytree(bag, folder / bag.name)
    found = check_demonstrations(folder, window_frames=WINDOW)
    assert found.clips_per_label() == {'forward': 3, 'leftward': 0, 'rightward': 0}
    assert found.labels_present == ('forward',) and found.labels_missing == ('leftward', 'rightward')
    assert 'no clip labelled leftward, rightward' in found.describe()


def test_a_ur_driver_recording_at_125_hz_passes(tmp_path):
    bag = tmp_path / 'rightward_2025-11-21-10-00-00'
    write_driver_bag(bag, SWING, SWING.total_s, label='rightward')
    found = check_demonstrations(bag, window_frames=WINDOW)
    assert found.clips_per_label()['rightward'] == 1
    assert found.bags[0].rate_hz == pytest.approx(125.0, rel=0.01)


def test_other_tools_label_a_take_by_its_name_or_its_folder(tmp_path):
    """No custom_data label: a direction among the name's words, else the folder it sits in."""
    folder = tmp_path / 'demos'
    takes = {
        'take3-Leftward': 'leftward',
        'Forward01': 'forward',
        'rightward/take_7': 'rightward',
        'forward/clip': 'forward',
        'leftward/rightward_2': 'rightward',
    }
    for name in takes:
        write_driver_bag(folder / name, SWING, SWING.total_s, label=None)
    found = check_demonstrations(folder, window_frames=WINDOW)
    assert {bag.bag.relative_to(folder).as_posix(): bag.label for bag in found.bags} == takes

    both = tmp_path / 'both' / 'forward_or_leftward'
    write_driver_bag(both, SWING, SWING.total_s, label=None)
    assert_one_line_naming(refusal(both.parent), both, 'unlabelled', "folder's name")


def test_a_missing_path_and_a_folder_without_bags_are_refused(tmp_path):
    assert refusal(tmp_path / 'nowhere') == f'{tmp_path / "nowhere"}: does not exist'
    empty = tmp_path / 'empty'
    (empty / 'sub').mkdir(parents=True)
    (empty / 'notes.txt').write_text('no bags here')
    assert_one_line_naming(refusal(empty), empty, 'no rosbag2 bag')


def test_a_damaged_bag_is_refused_by_name_among_good_ones(good_folder):
    bag = good_folder / 'forward_20250101_120000_000'
    truncate_file(next(bag.glob('*.mcap')))
    assert_one_line_naming(refusal(good_folder), bag, 'cannot be read', 'truncated')


def test_unlabelled_and_unknown_labels_are_refused(tmp_path):
    unlabelled = tmp_path / 'unlabelled' / 'take1'
    write_recorder_bag(unlabelled, SWING, SWING.total_s, label=None)
    assert_one_line_naming(refusal(unlabelled.parent), unlabelled, 'unlabelled', 'forward, leftward, rightward')
    backhand = tmp_path / 'unknown' / 'backhand_20250101_120000_000'
    write_recorder_bag(backhand, SWING, SWING.total_s, label='backhand')
    assert_one_line_naming(refusal(backhand.parent), backhand, "unknown label 'backhand'")


def test_another_robots_joints_are_refused(tmp_path):
    store = jazzy_typestore()
    names = [f'joint_{k}' for k in range(1, 8)]  # a seven-joint arm
    times_s = np.arange(0, SWING.total_s, 1 / 200)
    q, qd = SWING(times_s)
    messages = []
    for t_s, position, velocity in zip(times_s, q, qd):
        stamp = EPOCH_NS + int(round(t_s * 1e9))
        messages.append((stamp, joint_state_cdr(store, stamp, names, [*position, 0.0], [*velocity, 0.0])))
    bag = tmp_path / 'other' / 'forward_20250101_120000_000'
    write_raw_bag(bag, {'/joint_states': messages}, label='forward')
    message = refusal(bag.parent)
    assert_one_line_naming(message, bag, "not the UR5's", 'joint_7')
    assert '--joints' not in message


def test_positions_outside_the_joint_limits_are_refused(tmp_path):
    elbow_past_pi = Swing(end_rad=(0.6, -1.3, 3.4, -0.8, -1.2, 2.0))  # the elbow stops at +-pi
    bag = tmp_path / 'limits' / 'forward_20250101_120000_000'
    write_recorder_bag(bag, elbow_past_pi, elbow_past_pi.total_s)
    assert_one_line_naming(refusal(bag.parent), bag, 'elbow_joint', "outside the UR5's limits", '3.142')


def test_a_rate_too_low_for_60_hz_is_refused(tmp_path):
    bag = tmp_path / 'slow' / 'forward_20250101_120000_000'
    write_recorder_bag(bag, SWING, SWING.total_s, rate_hz=30.0)
    assert_one_line_naming(refusal(bag.parent), bag, '30.0 Hz', 'too slow')
    assert MIN_RATE_HZ < 60.0


def test_a_clip_too_short_for_the_window_at_x5_is_refused(tmp_path):
    flick = Swing(duration_s=0.4)
    bag = tmp_path / 'short' / 'leftward_20250101_120000_000'
    write_recorder_bag(bag, flick, flick.total_s, label='leftward')
    message = refusal(bag.parent)
    assert_one_line_naming(message, bag, 'too short', 'x5', f'window of {WINDOW}')
    # The same clip passes a window it does fill.
    frames = int(message.split(' frames at ')[0].rsplit('(', 1)[1])
    assert frames_after_speedup(frames, 5) < WINDOW
    check_demonstrations(bag.parent, window_frames=frames_after_speedup(frames, 5))


def test_one_line_per_bad_bag_and_none_for_good_ones(good_folder):
    slow = good_folder / 'rightward_20250101_130000_000'
    write_recorder_bag(slow, SWING, SWING.total_s, rate_hz=20.0, label='rightward')
    unknown = good_folder / 'smash_20250101_130000_000'
    write_recorder_bag(unknown, SWING, SWING.total_s, label='smash')
    with pytest.raises(DemonstrationError) as caught:
        check_demonstrations(good_folder, window_frames=WINDOW)
    assert len(caught.value.lines) == 2
    assert {line.split(': ')[0] for line in caught.value.lines} == {str(slow), str(unknown)}


def test_a_dataset_passes_or_is_refused_naming_the_bag_of_the_bad_clips(tmp_path):
    found = check_demonstrations(SHIPPED_BAGS, window_frames=WINDOW)
    good = found.reference_dataset().save(tmp_path / 'good.npz')
    again = check_demonstrations(good, window_frames=WINDOW)
    assert again.kind == 'dataset' and again.speedups == (2, 3, 5)
    assert again.clips_per_label() == found.clips_per_label()
    assert again.reference_dataset().num_clips == 28

    dataset = ReferenceDataset.load(good)
    bag = str(dataset.source[0]).rsplit(':', 1)[0]
    dataset.label = np.where(dataset.source == dataset.source[0], 'unlabelled', dataset.label)
    dataset.save(tmp_path / 'unlabelled.npz')
    message = refusal(tmp_path / 'unlabelled.npz')
    assert '\n' not in message and bag in message and 'unlabelled clips' in message

    dataset = ReferenceDataset.load(good)
    dataset.q[:, 2] += 3.0  # every clip's elbow beyond pi
    dataset.save(tmp_path / 'limits.npz')
    with pytest.raises(DemonstrationError) as caught:
        check_demonstrations(tmp_path / 'limits.npz', window_frames=WINDOW)
    assert len(caught.value.lines) == 7 and all('elbow_joint' in line for line in caught.value.lines)

    # The x5 clips of the shipped set hold 26-35 frames: a window of 30 leaves some without one.
    message = refusal(good, window_frames=30)
    assert 'x5' in message and 'window of 30' in message

    dataset = ReferenceDataset.load(good)
    dataset.joint_names = tuple(f'joint_{k}' for k in range(1, 7))
    dataset.save(tmp_path / 'other_robot.npz')
    assert "are not the UR5's" in refusal(tmp_path / 'other_robot.npz')

    (tmp_path / 'broken.npz').write_bytes(b'not a zip')
    assert_one_line_naming(refusal(tmp_path / 'broken.npz'), tmp_path / 'broken.npz', 'not a dataset')


def test_a_refusal_comes_fast_without_torch(tmp_path):
    bag = tmp_path / 'bad' / 'take1'
    write_recorder_bag(bag, SWING, SWING.total_s, label=None)
    script = (
        'import sys\n'
        'from stylepong_policy.training.demo_check import DemonstrationError, check_demonstrations\n'
        f'try:\n    check_demonstrations({str(bag.parent)!r}, window_frames=8)\n'
        'except DemonstrationError as error:\n    print(error)\n'
        "print('torch imported' if 'torch' in sys.modules else 'no torch')\n"
    )
    started = time.perf_counter()
    done = subprocess.run([sys.executable, '-c', script], capture_output=True, text=True, timeout=60)
    elapsed_s = time.perf_counter() - started
    assert done.returncode == 0, done.stderr
    assert done.stdout.splitlines() == [
        f'{bag}: unlabelled (no label in metadata.yaml custom_data, its directory '
        "name or its folder's name); label it forward, leftward, rightward",
        'no torch',
    ]
    assert elapsed_s < 15.0
