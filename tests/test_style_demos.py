"""The demonstration sets in other styles (demonstrations/<name>, recorded by tools/record_demos.sh with a style
file): each is seven clips, 3 forward / 2 leftward / 2 rightward, joint states at 125 Hz as a CB3 UR driver
publishes them, dragged slowly, and a style of its own: its clips are nearer one another than to the shipped
clips (ros2_ws/bags) and to another set's, label by label (mean DTW, style_metrics).
"""

import contextlib
import io
import itertools
import pathlib

import numpy as np
import pytest

from stylepong_policy.evaluation.style_metrics import dtw_distance_rad, smoothness
from stylepong_policy.training import build_dataset
from stylepong_policy.training.dataset import ReferenceDataset
from stylepong_recording.bag_reading import median_rate_hz, read_joint_states

ROOT = pathlib.Path(__file__).resolve().parent.parent
SETS = sorted(p for p in (ROOT / 'demonstrations').iterdir() if p.is_dir())
EXPECTED_LABELS = {'forward': 3, 'leftward': 2, 'rightward': 2}
JOINTS = build_dataset.default_joint_names()
CB3_RATE_HZ = 125.0
# Dragged slowly: a person careful with a UR5 moves its fastest joint at about 1 rad/s; the dragged arm
# overshoots the hand's path a little, and the arm's own limit is 3.14 rad/s.
MAX_PEAK_JOINT_SPEED_RAD_S = 2.5
MAX_MEDIAN_PEAK_JOINT_SPEED_RAD_S = 1.5


def _dataset(bags: pathlib.Path, out: pathlib.Path) -> ReferenceDataset:
    with contextlib.redirect_stdout(io.StringIO()) as report:
        code = build_dataset.run([str(bags), '-o', str(out)])
    assert code == 0, report.getvalue()
    return ReferenceDataset.load(out)


@pytest.fixture(scope='module')
def datasets(tmp_path_factory) -> dict[str, ReferenceDataset]:
    out = tmp_path_factory.mktemp('style_sets')
    found = {'shipped': _dataset(ROOT / 'ros2_ws' / 'bags', out / 'shipped.npz')}
    found.update({path.name: _dataset(path, out / f'{path.name}.npz') for path in SETS})
    return found


def _originals(dataset: ReferenceDataset, label: str | None = None) -> list[np.ndarray]:
    return [
        dataset.clip(int(i)).q for i in dataset.select(labels=None if label is None else [label], speed_factors=[1])
    ]


def _mean_dtw_rad(a: list[np.ndarray], b: list[np.ndarray] | None = None) -> float:
    pairs = itertools.combinations(a, 2) if b is None else itertools.product(a, b)
    return float(np.mean([dtw_distance_rad(x, y) for x, y in pairs]))


def test_there_are_at_least_two_sets():
    assert len(SETS) >= 2, [p.name for p in SETS]


@pytest.mark.parametrize('bags', SETS, ids=lambda p: p.name)
def test_a_set_is_seven_labelled_clips_recorded_at_a_cb3_drivers_rate(bags):
    clips = sorted(p for p in bags.iterdir() if p.is_dir())
    labels = [p.name.split('_')[0] for p in clips]
    assert {label: labels.count(label) for label in set(labels)} == EXPECTED_LABELS
    for clip in clips:
        recording = read_joint_states(clip, joints=JOINTS)
        assert median_rate_hz(recording.header_stamp_ns) == pytest.approx(CB3_RATE_HZ, rel=0.02), clip.name


def test_every_set_is_dragged_slowly_and_has_the_expected_clips(datasets):
    for name, dataset in datasets.items():
        if name == 'shipped':
            continue
        for label, count in EXPECTED_LABELS.items():
            assert len(_originals(dataset, label)) == count, (name, label)
        peaks = [smoothness(q, dataset.rate_hz).peak_joint_speed_rad_s for q in _originals(dataset)]
        assert max(peaks) < MAX_PEAK_JOINT_SPEED_RAD_S, (name, peaks)
        assert float(np.median(peaks)) < MAX_MEDIAN_PEAK_JOINT_SPEED_RAD_S, (name, peaks)


def test_each_set_is_a_style_of_its_own(datasets):
    """Per label, a set's clips are nearer one another than to any other set's (the shipped ones included)."""
    for name, label in itertools.product([n for n in datasets if n != 'shipped'], EXPECTED_LABELS):
        own = _originals(datasets[name], label)
        within = _mean_dtw_rad(own)
        for other in datasets:
            if other != name:
                between = _mean_dtw_rad(own, _originals(datasets[other], label))
                assert within < between, f'{name} {label}: {within:.1f} rad within, {between:.1f} to {other}'
