"""Hand-made stroke styles (stroke_styles.py, config/styles/*.yaml): read, checked, and played by the teacher."""

import pathlib

import numpy as np
import pytest
import rclpy
import yaml

from stylepong_common.node_support import ParameterError
from stylepong_sim.nodes.virtual_teacher_node import VirtualTeacherNode
from stylepong_sim.teaching import stroke_styles
from stylepong_sim.teaching.teacher import STROKES, SWINGS, StrokePath, SwingVariation, TeacherConfig, sample_variation

STYLE_FILES = sorted(stroke_styles.STYLES_DIR.glob('*.yaml'))
KINEMATICS = stroke_styles.StrokeKinematics()
HOME_CENTRE = KINEMATICS.kin.pose(KINEMATICS.home_q, KINEMATICS.centre).translation


def _entry(shape) -> dict:
    return {
        'back_offset_m': list(shape.back_offset_m),
        'hit_offset_m': list(shape.hit_offset_m),
        'follow_offset_m': list(shape.follow_offset_m),
        'yaw_rad': [shape.back_yaw_rad, shape.hit_yaw_rad, shape.follow_yaw_rad],
    }


def _write(tmp_path: pathlib.Path, document) -> pathlib.Path:
    path = tmp_path / 'style.yaml'
    path.write_text(document if isinstance(document, str) else yaml.safe_dump(document))
    return path


def test_the_shipped_styles_exist_and_teach_all_three_swings():
    assert {p.stem for p in STYLE_FILES} >= {'long', 'compact'}
    for path in STYLE_FILES:
        assert set(stroke_styles.load_strokes_file(path)) == set(SWINGS), path


@pytest.mark.parametrize('path', STYLE_FILES, ids=lambda p: p.stem)
def test_every_take_of_a_shipped_style_is_a_clean_unmistakable_stroke(path):
    """The nominal take and the seeds tools/record_demos.sh gives its seven clips (1-7)."""
    for swing, shape in stroke_styles.load_strokes_file(path).items():
        for variation in [SwingVariation()] + [sample_variation(swing, seed) for seed in range(1, 8)]:
            check = stroke_styles.check_stroke(
                swing, StrokePath(swing, TeacherConfig(), HOME_CENTRE, variation, shape), KINEMATICS
            )
            assert check.min_shoulder_clearance_m >= stroke_styles.MIN_SHOULDER_CLEARANCE_M


def test_the_shipped_strokes_written_as_a_style_file_give_the_same_path(tmp_path):
    """Without pitch_rad a file's stroke is the shipped one, bit for bit (the blade held at blade_pitch_rad)."""
    strokes = stroke_styles.load_strokes_file(_write(tmp_path, {s: _entry(STROKES[s]) for s in SWINGS}))
    for swing in SWINGS:
        take = sample_variation(swing, 3)
        shipped = StrokePath(swing, TeacherConfig(), HOME_CENTRE, take)
        from_file = StrokePath(swing, TeacherConfig(), HOME_CENTRE, take, strokes[swing])
        for t in np.linspace(0.0, shipped.duration_s, 37):
            a, b = shipped.at(t), from_file.at(t)
            np.testing.assert_array_equal(a.position_m, b.position_m)
            assert (a.yaw_rad, a.pitch_rad, a.pitch_rate_rad_s) == (b.yaw_rad, b.pitch_rad, b.pitch_rate_rad_s)


def test_key_pose_pitches_open_the_blade_through_the_stroke(tmp_path):
    entry = {**_entry(STROKES['forward']), 'pitch_rad': [0.1, 0.5, 0.9]}
    shape = stroke_styles.load_strokes_file(_write(tmp_path, {'forward': entry}))['forward']
    path = StrokePath('forward', TeacherConfig(), HOME_CENTRE, SwingVariation(), shape)
    back_s = path.config.lead_in_s + path.backswing_s
    assert path.at(0.0).pitch_rad == 0.0
    assert path.at(back_s).pitch_rad == pytest.approx(0.1)
    assert path.at(path.hit_time_s()).pitch_rad == pytest.approx(0.5)
    assert path.at(path.duration_s).pitch_rad == pytest.approx(0.9)
    assert path.at(path.hit_time_s()).pitch_rate_rad_s > 0.0


@pytest.mark.parametrize(
    'document, words',
    [
        ('forward: [1, 2', 'not YAML'),
        ({'backhand': {}}, 'unknown swing(s) backhand'),
        ({'forward': {'back_offset_m': [0.0, 0.0, 0.0]}}, 'forward: missing hit_offset_m'),
        ({'forward': {**_entry(STROKES['forward']), 'roll_rad': [0, 0, 0]}}, 'unknown key(s) roll_rad'),
        ({'forward': {**_entry(STROKES['forward']), 'hit_offset_m': [0.1, 0.0]}}, 'hit_offset_m must be a list of 3'),
        ({'forward': {**_entry(STROKES['forward']), 'yaw_rad': [0.0, 2.0, 0.0]}}, 'yaw_rad must stay within'),
        ({'forward': {**_entry(STROKES['forward']), 'pitch_rad': [0.0, -0.2, 0.0]}}, 'pitch_rad opens the blade'),
        ({'forward': {**_entry(STROKES['forward']), 'follow_offset_m': [0.9, 0.0, 0.0]}}, 'm from home'),
    ],
)
def test_a_malformed_style_file_is_refused_in_one_line_naming_the_file_and_the_fault(tmp_path, document, words):
    path = _write(tmp_path, document)
    with pytest.raises(ValueError) as error:
        stroke_styles.load_strokes_file(path)
    assert str(path) in str(error.value) and words in str(error.value) and '\n' not in str(error.value)


def test_a_missing_style_file_is_refused_naming_it(tmp_path):
    with pytest.raises(ValueError, match='cannot read it'):
        stroke_styles.load_strokes_file(tmp_path / 'nowhere.yaml')
    assert stroke_styles.resolve_strokes_file('long') == stroke_styles.STYLES_DIR / 'long.yaml'
    assert stroke_styles.resolve_strokes_file('mine.yaml') == pathlib.Path('mine.yaml')


def _checked(swing: str, **changes) -> stroke_styles.StrokeCheck:
    shape = STROKES[swing]
    entry = {**_entry(shape), **changes}
    strokes = stroke_styles.shape_from_mapping(entry, 'test')
    return stroke_styles.check_stroke(
        swing, StrokePath(swing, TeacherConfig(blade_pitch_rad=0.0), HOME_CENTRE, SwingVariation(), strokes), KINEMATICS
    )


def test_a_stroke_whose_label_could_be_mistaken_is_refused():
    _checked('leftward')  # the shipped one passes
    with pytest.raises(ValueError, match='leftward stroke meets the ball'):
        _checked('leftward', hit_offset_m=[0.03, -0.05, 0.05])  # met on the right
    with pytest.raises(ValueError, match='leftward stroke meets the ball'):
        _checked('leftward', yaw_rad=[-0.1, -0.1, 0.45])  # facing right at the hit
    with pytest.raises(ValueError, match='forward stroke meets the ball straight ahead'):
        _checked('forward', hit_offset_m=[0.06, 0.08, 0.05])
    with pytest.raises(ValueError, match='back-swing'):
        _checked('forward', back_offset_m=[0.02, -0.06, -0.07])  # no back-swing


def test_a_stroke_near_the_shoulder_singularity_or_beyond_reach_is_refused():
    with pytest.raises(ValueError, match='shoulder singularity'):
        _checked('forward', back_offset_m=[-0.25, -0.06, -0.07])
    with pytest.raises(ValueError, match='elbow straightens|cannot reach'):
        _checked('forward', follow_offset_m=[0.50, -0.02, 0.30])


def _node(*ros_args: str) -> tuple[VirtualTeacherNode, rclpy.Context]:
    context = rclpy.Context()
    rclpy.init(args=['--ros-args', *ros_args], context=context)
    return VirtualTeacherNode(context=context), context


def test_the_teacher_plays_a_style_named_by_its_file_or_its_name():
    expected = stroke_styles.load_strokes_file(stroke_styles.STYLES_DIR / 'long.yaml')['rightward']
    for value in ('long', str(stroke_styles.STYLES_DIR / 'long.yaml')):
        node, context = _node('-p', 'swing:=rightward', '-p', f'strokes_file:={value}', '-p', 'seed:=3')
        try:
            assert node.teacher.path.nominal_shape == expected
        finally:
            node.destroy_node()
            rclpy.try_shutdown(context=context)


@pytest.mark.parametrize(
    'document, words',
    [
        ({'forward': _entry(STROKES['forward'])}, 'has no leftward stroke'),
        ({'leftward': {**_entry(STROKES['leftward']), 'hit_offset_m': [0.03, -0.05, 0.05]}}, 'leftward take (seed 2)'),
        ('leftward: 3', 'expected a mapping'),
    ],
)
def test_a_style_the_teacher_cannot_play_is_refused_naming_strokes_file(tmp_path, document, words):
    path = _write(tmp_path, document)
    context = rclpy.Context()
    rclpy.init(
        args=['--ros-args', '-p', 'swing:=leftward', '-p', 'seed:=2', '-p', f'strokes_file:={path}'], context=context
    )
    try:
        with pytest.raises(ParameterError) as error:
            VirtualTeacherNode(context=context)
        message = str(error.value)
        assert message.startswith('parameter strokes_file:') and words in message and '\n' not in message
    finally:
        rclpy.try_shutdown(context=context)
