"""The space of drawn stroke styles (style_space.py) and tools/drawn_styles.py, which writes and splits them."""

import dataclasses
import json
import pathlib
import subprocess
import sys

import numpy as np
import pytest
import yaml

from stylepong_sim.teaching import stroke_styles, style_space
from stylepong_sim.teaching.teacher import STROKES, SWINGS, StrokePath, sample_variation

ROOT = pathlib.Path(__file__).resolve().parents[4]
KINEMATICS = stroke_styles.StrokeKinematics()
HOME_CENTRE = KINEMATICS.kin.pose(KINEMATICS.home_q, KINEMATICS.centre).translation
# The hand-made sets' tempos (backswing_s, forward_swing_s), from demonstrations/README.md's commands.
HAND_MADE_TEMPOS_S = {'compact': (0.8, 1.2), 'lift': (1.4, 2.6), 'long': (1.6, 3.0), 'wristy': (1.4, 3.0)}


def _key_pose_array(parameters: style_space.StyleParameters) -> np.ndarray:
    """Every key-pose number of a style in one array [swing, key, 3]."""
    poses = style_space.key_poses(parameters)
    return np.array([[poses[swing][key] for key in stroke_styles.KEYS] for swing in SWINGS])


def _key_pose_bounds() -> tuple[np.ndarray, np.ndarray]:
    """The lowest and highest value of each key-pose number over the box of parameter ranges.

    Each number is a fixed sum of parameters (affine), so its extremes are the middle's plus, parameter by
    parameter, the lower and the higher of the changes that parameter makes from its low or high end.
    """
    ranges = style_space.parameter_ranges()
    middle = style_space.StyleParameters(**{name: 0.5 * (low + high) for name, (low, high) in ranges.items()})
    centre = _key_pose_array(middle)
    low, high = centre.copy(), centre.copy()
    for name, ends in ranges.items():
        changes = [_key_pose_array(dataclasses.replace(middle, **{name: end})) - centre for end in ends]
        low += np.minimum(*changes)
        high += np.maximum(*changes)
    return low, high


def test_the_key_poses_are_affine_in_the_parameters_so_the_bounds_are_exact():
    ranges = style_space.parameter_ranges()
    middle = style_space.StyleParameters(**{name: 0.5 * (low + high) for name, (low, high) in ranges.items()})
    rng = np.random.default_rng(0)
    for _ in range(5):
        drawn = style_space.draw_style(rng)
        summed = _key_pose_array(middle) + sum(
            _key_pose_array(dataclasses.replace(middle, **{name: getattr(drawn, name)})) - _key_pose_array(middle)
            for name in ranges
        )
        np.testing.assert_allclose(_key_pose_array(drawn), summed, atol=1e-3)


@pytest.mark.parametrize('name', sorted(HAND_MADE_TEMPOS_S))
def test_the_space_brackets_every_hand_made_style(name):
    low, high = _key_pose_bounds()
    document = yaml.safe_load((stroke_styles.STYLES_DIR / f'{name}.yaml').read_text())
    hand_made = np.array([[document[swing][key] for key in stroke_styles.KEYS] for swing in SWINGS])
    outside = [
        f'{swing} {key}[{axis}] = {hand_made[i, j, axis]} not in [{low[i, j, axis]:.3f}, {high[i, j, axis]:.3f}]'
        for i, swing in enumerate(SWINGS)
        for j, key in enumerate(stroke_styles.KEYS)
        for axis in range(3)
        if not low[i, j, axis] - 1e-9 <= hand_made[i, j, axis] <= high[i, j, axis] + 1e-9
    ]
    assert not outside, outside
    backswing_s, forward_swing_s = HAND_MADE_TEMPOS_S[name]
    style_space.StyleParameters(backswing_s=backswing_s, forward_swing_s=forward_swing_s).validate()


def test_the_defaults_are_the_shipped_strokes_within_their_ranges():
    style_space.StyleParameters().validate()
    forward = stroke_styles.shape_from_mapping(style_space.key_poses(style_space.StyleParameters())['forward'], 'test')
    assert forward == dataclasses.replace(STROKES['forward'], pitch_rad=(0.6, 0.6, 0.6))
    with pytest.raises(ValueError, match='backswing_s must be in'):
        style_space.StyleParameters(backswing_s=0.5).validate()


def test_draws_are_reproducible_from_the_seed_and_lie_in_the_space():
    first = [style_space.draw_style(np.random.default_rng(11)) for _ in range(2)]
    assert first[0] == first[1]
    rng = np.random.default_rng(12)
    draws = [style_space.draw_style(rng) for _ in range(200)]
    for drawn in draws:
        drawn.validate()
    assert len(set(draws)) == len(draws)
    assert all(style_space.draw_style(np.random.default_rng(11)) != drawn for drawn in draws)


def test_every_drawn_style_passes_the_checks_the_hand_made_ones_meet(tmp_path):
    """A checked draw, written as a style file and read back, passes stroke_styles on every recorded take."""
    checked = style_space.draw_checked_style(np.random.default_rng(1), KINEMATICS)
    assert all(isinstance(reason, str) and reason for reason in checked.rejections)
    path = tmp_path / 'style.yaml'
    path.write_text(yaml.safe_dump(style_space.key_poses(checked.parameters)))
    strokes = stroke_styles.load_strokes_file(path)
    config = style_space.teacher_config(checked.parameters)
    for seed_of_clip, swing in zip(style_space.RECORDED_SEEDS, style_space.RECORDING_ORDER):
        variation = sample_variation(swing, seed_of_clip)
        path_of_take = StrokePath(swing, config, HOME_CENTRE, variation, strokes[swing])
        stroke_styles.check_stroke(swing, path_of_take, KINEMATICS)


def test_a_style_the_checks_refuse_is_named_with_its_reason():
    shipped = style_space.StyleParameters()  # the shipped strokes, their blade opened from the back-swing on
    assert style_space.style_problem(shipped, KINEMATICS).startswith('leftward nominal: the wrist passes')
    too_quick = style_space.StyleParameters(backswing_s=0.5)
    assert style_space.style_problem(too_quick, KINEMATICS).startswith('backswing_s must be in')


def test_the_split_is_a_seeded_disjoint_shuffle():
    names = [f'style_{k}' for k in range(9)]
    split = style_space.split_tuning_heldout(names, np.random.default_rng(4))
    assert split == style_space.split_tuning_heldout(names, np.random.default_rng(4))
    assert not set(split['tuning']) & set(split['heldout'])
    assert sorted(split['tuning'] + split['heldout']) == sorted(names)
    assert (len(split['tuning']), len(split['heldout'])) == (5, 4)
    assert split != style_space.split_tuning_heldout(names, np.random.default_rng(5))


def _tool(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, str(ROOT / 'tools' / 'drawn_styles.py'), *args], capture_output=True, text=True, check=False
    )


@pytest.mark.slow  # 5-11 s on the 2-core machine (draws and checks styles): .ci/run runs it, `make test` skips it
def test_generate_writes_checked_style_files_and_records_the_split(tmp_path):
    result = _tool('generate', '--count', '2', '--seed', '3', '--out', str(tmp_path))
    assert result.returncode == 0, result.stderr
    split = json.loads((tmp_path / 'split.json').read_text())
    assert (split['seed'], split['count'], list(split['styles'])) == (3, 2, ['style_0', 'style_1'])
    assert sorted(split['tuning'] + split['heldout']) == ['style_0', 'style_1'] and len(split['heldout']) == 1
    assert split['rejected'] == sum(len(s['rejected_draws']) for s in split['styles'].values())
    draws = np.random.default_rng([3, 0])  # the tool's stream of draws: the seed gives every style again
    for name, style in split['styles'].items():
        for _ in style['rejected_draws']:
            style_space.draw_style(draws)
        parameters = style_space.StyleParameters(**style['parameters'])
        assert parameters == style_space.draw_style(draws)
        read_back = stroke_styles.load_strokes_file(tmp_path / style['file'])
        expected = {
            swing: stroke_styles.shape_from_mapping(entry, swing)
            for swing, entry in style_space.key_poses(parameters).items()
        }
        assert read_back == expected

    record = _tool(
        'record', '--split', str(tmp_path / 'split.json'), '--which', 'heldout', '--out', str(tmp_path), '--dry-run'
    )
    assert record.returncode == 0, record.stderr
    heldout = split['styles'][split['heldout'][0]]['parameters']
    assert f'BACKSWING_S={heldout["backswing_s"]:.2f}' in record.stdout and 'JOINT_STATE_RATE_HZ=125.0' in record.stdout
    assert 'record_demos.sh --out' in record.stdout and ' '.join(style_space.RECORDING_ORDER) in record.stdout
