"""`evaluate` with --save-strokes and --dtw on the shipped PPO actor (1 seed, a few balls), and
`run_evaluation`, the function other code calls."""

import json
import pathlib

import numpy as np
import pytest
from json_text import json_strings  # beside this file: conftest.py
from synthetic_reference import write_reference

from stylepong_policy.evaluation import evaluate, strokes

PACKAGE = pathlib.Path(__file__).resolve().parents[1]
PPO_ACTOR = PACKAGE / 'models' / 'ppo_actor.pt'
BALLS = 12
SEED = 1000


@pytest.fixture(scope='module')
def evaluated(tmp_path_factory):
    folder = tmp_path_factory.mktemp('evaluate')
    write_reference(folder / 'reference.npz')
    with pytest.MonkeyPatch.context() as patch:
        patch.chdir(folder)  # relative paths, as a person types them
        status = evaluate.main(
            [
                '--actor',
                str(PPO_ACTOR),
                '--seeds',
                '1',
                '--first-seed',
                str(SEED),
                '--balls',
                str(BALLS),
                '--save-strokes',
                'out/strokes.npz',
                '--dtw',
                'reference.npz',
                '--json',
                'out/eval.json',
                '--num-threads',
                '1',
            ]
        )
    assert status == 0
    return folder


def test_stroke_file_holds_every_ball_from_launch_to_the_follow_through(evaluated):
    saved = strokes.load_strokes(evaluated / 'out' / 'strokes.npz')
    assert len(saved.strokes) == BALLS and saved.rate_hz == 60.0 and saved.speed == 'all'
    assert saved.actor == 'ppo_actor.pt'  # an absolute path outside the working folder: its name only
    assert [s.ball for s in saved.strokes] == list(range(BALLS)) and {s.seed for s in saved.strokes} == {SEED}
    for s in saved.strokes:
        assert s.direction in strokes.DIRECTIONS
        assert s.direction == strokes.direction_of(s.arrival_y_m)
        assert 4.0 <= s.launch_speed_m_s <= 6.6
        assert s.joint_positions_rad.shape == (len(s.ball_position_m), 6)
        assert s.joint_positions_rad.dtype == np.float32
        if s.hit:
            # From the launch (frame 0) to 0.3 s (18 frames) after the first contact, unless decided sooner.
            assert len(s.joint_positions_rad) == min(s.hit_frame + 18, s.verdict_frame) + 1
        else:
            assert len(s.joint_positions_rad) == s.verdict_frame + 1
        assert s.success == (s.outcome == evaluate.SUCCESS_REASON)
        # The ball starts over the opponent's half and the arm at home.
        assert s.ball_position_m[0, 0] > 0.0
        assert s.joint_positions_rad[0] == pytest.approx(np.array([0.0, -1.9, 1.9, -1.57, -1.57, -1.57]), abs=1e-5)
    # The same balls, labelled from their launch: the horizontal path is a straight line in this world.
    plane_x = strokes.paddle_home_position_m()[0]
    for s in saved.strokes:
        p, v = s.ball_position_m[0], s.launch_velocity_m_s
        assert s.arrival_y_m == pytest.approx(p[1] + (plane_x - p[0]) * v[1] / v[0], abs=1e-4)


def test_json_has_directions_smoothness_dtw_and_no_absolute_path(evaluated):
    result = json.loads((evaluated / 'out' / 'eval.json').read_text())
    assert result['balls'] == BALLS and result['seeds'] == [SEED]
    assert sum(d['balls'] for d in result['directions'].values()) == BALLS
    assert result['strokes_file'] == 'out/strokes.npz' and result['dtw_dataset'] == 'reference.npz'
    saved = strokes.load_strokes(evaluated / 'out' / 'strokes.npz')
    counts = {d: sum(s.direction == d for s in saved.strokes) for d in strokes.DIRECTIONS}
    for direction in strokes.DIRECTIONS:
        dtw = result['dtw'][direction]
        assert dtw['strokes'] == counts[direction] and dtw['reference_clips'] == 2
        if counts[direction]:
            assert dtw['mean_rad'] > 0 and 0 < dtw['mean_per_path_step_rad'] < dtw['mean_rad']
            assert result['smoothness'][direction]['peak_joint_speed_rad_s'] > 0
    # Every stroke falls in one lateral-offset band, and the bands' means average to the directions' means.
    bands = result['dtw_by_lateral_offset'].values()
    assert sum(b['strokes'] for b in bands) == BALLS
    by_direction = sum(d['mean_rad'] * d['strokes'] for d in result['dtw'].values() if d['strokes'])
    assert sum(b['mean_rad'] * b['strokes'] for b in bands if b['strokes']) == pytest.approx(by_direction)
    assert result['mean_successes_per_seed'] == pytest.approx(result['success_rate'] * BALLS)
    for text in json_strings(result):
        assert not text.startswith('/'), text


def test_dtw_in_the_json_is_recomputable_from_the_stroke_file(evaluated):
    from stylepong_policy.evaluation import style_metrics
    from stylepong_policy.training.dataset import ReferenceDataset

    result = json.loads((evaluated / 'out' / 'eval.json').read_text())
    dataset = ReferenceDataset.load(evaluated / 'reference.npz')
    saved = strokes.load_strokes(evaluated / 'out' / 'strokes.npz')
    for direction in strokes.DIRECTIONS:
        chosen = [s for s in saved.strokes if s.direction == direction]
        if not chosen:
            continue
        clips = [dataset.clip(int(c)).q for c in dataset.select(labels=[direction])]
        distances = [min(style_metrics.dtw_distance_rad(s.joint_positions_rad, c) for c in clips) for s in chosen]
        assert np.mean(distances) == pytest.approx(result['dtw'][direction]['mean_rad'], rel=1e-12)


def test_run_evaluation_returns_what_evaluate_prints(evaluated):
    summary = evaluate.run_evaluation(
        PPO_ACTOR, seeds=1, first_seed=SEED, balls=BALLS, speed='all', randomize=False, device='cpu'
    )
    printed = json.loads((evaluated / 'out' / 'eval.json').read_text())
    assert summary['per_seed'] == printed['per_seed'] and summary['failures'] == printed['failures']
    assert summary['directions'] == printed['directions'] and 'dtw' not in summary
    assert set(printed) - set(summary) == {
        'dtw',
        'dtw_by_lateral_offset',
        'dtw_dataset',
        'dtw_call',
        'strokes_file',
        'command',
    }
    assert printed['command'].startswith('ros2 run stylepong_policy evaluate --actor ')
    # A loaded actor is accepted as well, and the path it was loaded from is reported as given.
    from stylepong_policy.rl.export import load_actor

    again = evaluate.run_evaluation(load_actor(PPO_ACTOR), seeds=1, first_seed=SEED, balls=BALLS)
    assert again['per_seed'] == summary['per_seed']


def test_portable_path_keeps_relative_paths_and_never_writes_a_foreign_absolute_one(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert evaluate.portable_path('models/a.pt') == 'models/a.pt'
    assert evaluate.portable_path(tmp_path / 'x' / 'a.pt') == 'x/a.pt'
    assert evaluate.portable_path('/elsewhere/b.pt') == 'b.pt'


def test_a_stiff_drive_changes_the_world_and_the_result_says_so(tmp_path):
    """--velocity-drive 1 swaps the PD for a stiff joint motor (as Bullet's, as a UR's). The shipped actor,
    trained behind the PD alone, leans on its lag (docs/DESIGN.md, Known limits): its follow-through then
    drives the paddle into the table. A retrained actor may return more there; this pins today's."""
    actor = PACKAGE / 'models' / 'amp_actor.pt'
    results = {}
    for share in ('0', '1'):
        out = tmp_path / f'{share}.json'
        assert (
            evaluate.main(
                [
                    '--actor',
                    str(actor),
                    '--seeds',
                    '1',
                    '--first-seed',
                    '900',
                    '--balls',
                    '60',
                    '--velocity-drive',
                    share,
                    '--json',
                    str(out),
                    '--num-threads',
                    '1',
                ]
            )
            == 0
        )
        results[share] = json.loads(out.read_text())
    assert results['0']['success_rate'] >= 0.85 and results['1']['success_rate'] <= 0.6, results
    assert results['1']['failures'].get('table_contact_by_robot', 0) >= 10
    # Behind the PD it returns the balls, yet commands the arm below the table top for most of them.
    assert results['0']['commanded_into_table'] >= 0.5, results['0']['commanded_into_table']
    assert 'velocity motor' in results['1']['world'] and 'velocity motor' not in results['0']['world']


@pytest.mark.parametrize('flag, value', [('--velocity-drive', '1.5'), ('--armature-scale', 'nan')])
def test_a_drive_outside_its_range_is_refused(flag, value, capsys):
    with pytest.raises(SystemExit) as exit_info:
        evaluate.main(['--actor', str(PPO_ACTOR), flag, value])
    assert exit_info.value.code == 2 and flag in capsys.readouterr().err
