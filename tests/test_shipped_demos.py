"""The shipped demonstration clips (ros2_ws/bags, recorded by tools/record_demos.sh) as build_dataset gives them:
seven clean clips, 3 forward, 2 leftward, 2 rightward, same-label clips that are different takes, and the
very dataset the shipped style actors were trained on.

A style is learned from a distribution of takes, so two clips of one label must not be near-copies. They
are compared on normalised time (each clip resampled to the same number of frames from its first to its
last), which aligns takes of different lengths; what is left is the difference in path and pacing.
"""

import itertools
import json
import pathlib
import subprocess

import numpy as np
import pytest

from stylepong_policy.training.dataset import ReferenceDataset

ROOT = pathlib.Path(__file__).resolve().parent.parent
BAGS = ROOT / 'ros2_ws' / 'bags'
MODELS = ROOT / 'ros2_ws' / 'src' / 'stylepong_policy' / 'models'
EXPECTED_LABELS = {'forward': 3, 'leftward': 2, 'rightward': 2}

# Near-copies (one nominal stroke recorded again) differed by at most 0.0074 rad RMS; the seeded takes of
# the shipped set by 0.04 rad or more. Between the two, with room on both sides:
MIN_SAME_LABEL_RMS_RAD = 0.015
ALIGNED_FRAMES = 200
# Clean: no flip of the shoulder or wrist (a 60 Hz frame moves a joint by 0.05 rad at most in the shipped
# takes), and no stall within the stroke, from the first frame faster than 0.5 rad/s to the last (the arm
# rests for at most 0.07 s where the back-swing turns into the forward swing).
MAX_FRAME_STEP_RAD = 0.1
MAX_REST_S = 0.35
REST_SPEED_RAD_S = 0.05
SWING_SPEED_RAD_S = 0.5


@pytest.fixture(scope='module')
def shipped_path(tmp_path_factory) -> pathlib.Path:
    out = tmp_path_factory.mktemp('shipped') / 'dataset.npz'
    result = subprocess.run(
        ['ros2', 'run', 'stylepong_policy', 'build_dataset', str(BAGS), '-o', str(out)],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert result.returncode == 0, result.stdout + result.stderr
    return out


@pytest.fixture(scope='module')
def shipped(shipped_path) -> ReferenceDataset:
    return ReferenceDataset.load(shipped_path)


def originals(dataset: ReferenceDataset) -> list[int]:
    return [i for i in range(dataset.num_clips) if int(dataset.speed_factor[i]) == 1]


def on_normalised_time(q: np.ndarray, frames: int = ALIGNED_FRAMES) -> np.ndarray:
    old, new = np.linspace(0.0, 1.0, len(q)), np.linspace(0.0, 1.0, frames)
    return np.stack([np.interp(new, old, q[:, j]) for j in range(q.shape[1])], axis=1)


def longest_stall_s(qd: np.ndarray, rate_hz: float) -> float:
    """The longest rest within the stroke: from the first frame that swings to the last. Before and after
    it the arm settles at the ready pose and creeps off or comes to rest, which is no stall."""
    speed = np.linalg.norm(qd, axis=1)
    swinging = np.flatnonzero(speed > SWING_SPEED_RAD_S)
    if len(swinging) == 0:
        return len(qd) / rate_hz
    inside = speed[swinging[0] : swinging[-1] + 1] < REST_SPEED_RAD_S
    longest = run = 0
    for frame_rests in inside:
        run = run + 1 if frame_rests else 0
        longest = max(longest, run)
    return longest / rate_hz


def test_seven_clips_three_forward_two_leftward_two_rightward(shipped):
    labels = [str(shipped.label[i]) for i in originals(shipped)]
    assert {label: labels.count(label) for label in set(labels)} == EXPECTED_LABELS


def test_every_clip_is_clean(shipped):
    for i in originals(shipped):
        clip = shipped.clip(i)
        step_rad = float(np.max(np.abs(np.diff(clip.q, axis=0))))
        assert step_rad < MAX_FRAME_STEP_RAD, f'clip {i} ({shipped.label[i]}): a joint jumps {step_rad:.3f} rad'
        stall_s = longest_stall_s(clip.qd, shipped.rate_hz)
        assert stall_s < MAX_REST_S, f'clip {i} ({shipped.label[i]}): the arm stops for {stall_s:.2f} s'


def test_same_label_clips_are_not_near_copies(shipped):
    clips = originals(shipped)
    for a, b in itertools.combinations(clips, 2):
        if shipped.label[a] != shipped.label[b]:
            continue
        difference = on_normalised_time(shipped.clip(a).q) - on_normalised_time(shipped.clip(b).q)
        rms_rad = float(np.sqrt(np.mean(difference**2)))
        assert rms_rad > MIN_SAME_LABEL_RMS_RAD, (
            f'{shipped.label[a]} clips {a} and {b} differ by only {rms_rad:.4f} rad RMS: near-copies'
        )


def bag_names(sources: np.ndarray) -> list[str]:
    """'ros2_ws/bags/forward_x:/joint_states' -> 'forward_x:/joint_states': the bag's folder name and topic."""
    names = []
    for source in sources.tolist():
        bag, topic = source.rsplit(':', 1)
        names.append(f'{pathlib.PurePosixPath(bag).name}:{topic}')
    return names


@pytest.mark.parametrize('name', ['amp', 'amp_noaug'])
def test_the_shipped_style_actors_were_trained_on_these_clips(shipped_path, name):
    """The dataset a shipped actor's summary names holds the same frames as the one built here from the
    shipped bags; only the folder the bags were recorded into may differ."""
    trained_on = ROOT / json.loads((MODELS / f'{name}_summary.json').read_text())['dataset']
    with np.load(trained_on) as trained, np.load(shipped_path) as built:
        assert sorted(trained.files) == sorted(built.files)
        for key in trained.files:
            if key == 'source':
                assert bag_names(trained[key]) == bag_names(built[key])
            else:
                np.testing.assert_array_equal(trained[key], built[key], err_msg=key)
