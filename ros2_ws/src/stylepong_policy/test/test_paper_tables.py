"""`paper_tables` on a tiny setting, the shipped PPO actor standing in for every row."""

import json
import pathlib

import pytest
from json_text import json_strings  # beside this file: conftest.py

from stylepong_policy.reports import paper_tables

PACKAGE = pathlib.Path(__file__).resolve().parents[1]
PPO_ACTOR = PACKAGE / 'models' / 'ppo_actor.pt'
REPOSITORY = PACKAGE.parents[2]


def stand_ins() -> str:
    return ','.join(f'{name}={PPO_ACTOR}' for name in paper_tables.ACTOR_NAMES)


@pytest.fixture(scope='module')
def written(tmp_path_factory):
    out = tmp_path_factory.mktemp('results')
    (out / 'sim2sim_mujoco.json').write_text(
        json.dumps(
            {
                'simulator': 'MuJoCo cell',
                'success_rate': 0.5,
                'balls_per_seed': 10,
                'seeds': [1000, 1001],
                'actor': 'models/amp_actor.pt',
            }
        )
    )
    status = paper_tables.main(
        [
            '--out',
            str(out),
            '--actors',
            stand_ins(),
            '--seeds',
            '1',
            '--balls',
            '8',
            '--bags',
            str(REPOSITORY / 'ros2_ws' / 'bags'),
            '--num-threads',
            '1',
        ]
    )
    assert status == 0
    return out


@pytest.mark.slow  # over 7 s on the 2-core machine: .ci/run runs it, `make test` skips it
def test_markdown_has_every_table_with_the_papers_figures_beside_ours(written):
    text = (written / 'README.md').read_text()
    for heading in (
        '## Table I',
        '## Table II',
        '## Where the DTW distance lies',
        '## Table III',
        '## Smoothness',
        '## Table IV',
        '## Fig. 2',
    ):
        assert heading in text, heading
    for figure in ('96.27 %', '90.32 %', '148.23', '62.73', '0.423', '85.91 %', '71.39 %'):
        assert figure in text, figure  # the paper's, beside ours
    assert 'seed 1000 x 8 balls' in text and 'seed 2000 x 8 balls' in text
    assert 'Stand-in actors' in text
    assert 'MuJoCo cell (ours, `sim2sim_mujoco.json`)' in text and '50.00 %' in text
    for image in ('table1_success.png', 'table2_dtw.png', 'table3_speed.png', 'smoothness.png', 'strokes.png'):
        assert (written / image).stat().st_size > 5_000, image
        assert f']({image})' in text


def test_json_record_has_every_evaluation_and_no_absolute_path(written):
    record = json.loads((written / 'paper_tables.json').read_text())
    for name in paper_tables.ACTOR_NAMES:
        assert set(record['evaluations'][name]) == {'all', 'low', 'high'}
        assert record['evaluations'][name]['all']['balls'] == 8
        assert set(record['evaluations'][name]['all']['dtw']) == {'forward', 'leftward', 'rightward'}
    assert record['evaluations']['ppo']['low']['seeds'] == [2000]
    assert record['figure']['direction'] in ('forward', 'leftward', 'rightward')
    for text in json_strings(record):
        assert not text.startswith('/'), text
    assert (written / paper_tables.REFERENCE_NAME).is_file()


def test_without_sim2sim_files_table_four_says_not_measured(tmp_path):
    rows = paper_tables.load_sim2sim(tmp_path)
    assert rows == []
    (tmp_path / 'sim2sim_broken.json').write_text('{')
    assert 'unreadable' in paper_tables.load_sim2sim(tmp_path)[0]['error']


def test_table_four_lists_each_sim2sim_row_with_its_command(tmp_path):
    (tmp_path / 'sim2sim_pybullet_ideal.json').write_text(
        json.dumps(
            {
                'world': 'ur5_sim engine pybullet (PyBullet cell, Bullet contacts) through ROS, ideal actuator',
                'success_rate': 0.8,
                'success_rate_std': 0.05,
                'balls_per_seed': 20,
                'seeds': list(range(1000, 1010)),
                'actor': 'models/amp_actor.pt',
                'command': 'tools/sim2sim.sh --engine pybullet',
            }
        )
    )
    rows = paper_tables.load_sim2sim(tmp_path)
    assert rows[0]['command'] == 'tools/sim2sim.sh --engine pybullet' and rows[0]['mean_successes_per_seed'] == 16.0
    batched = {
        'balls_per_seed': 200,
        'mean_successes_per_seed': 190.5,
        'success_rate': 0.9525,
        'success_rate_std': 0.01,
        'actor': 'models/amp_actor.pt',
    }
    text = '\n'.join(paper_tables.table_four(rows, {'amp': {'all': batched}}, None))
    assert 'PyBullet cell, Bullet contacts' in text and '80.00 %' in text and '39.32 %' in text
    assert '`sim2sim_pybullet_ideal.json`: `tools/sim2sim.sh --engine pybullet`' in text


def test_a_missing_shipped_actor_fails_clearly(tmp_path, capsys):
    status = paper_tables.main(
        ['--out', str(tmp_path / 'r'), '--models-dir', str(tmp_path), '--actors', f'ppo={PPO_ACTOR}', '--no-figure']
    )
    assert status == 2
    error = capsys.readouterr().err
    assert 'amp-noaug' in error and 'amp_actor.pt' in error and '--actors' in error
    assert not (tmp_path / 'r').exists()


def test_actor_overrides_are_checked():
    assert paper_tables.parse_actor_overrides('ppo=a.pt,amp=b.pt') == {
        'ppo': pathlib.Path('a.pt'),
        'amp': pathlib.Path('b.pt'),
    }
    with pytest.raises(ValueError):
        paper_tables.parse_actor_overrides('dqn=a.pt')
    with pytest.raises(ValueError):
        paper_tables.parse_actor_overrides('ppo')


def test_the_speed_ups_effect_is_the_paired_difference_judged_by_its_standard_error():
    def summaries(amp, noaug):
        return {'amp': {'high': {'per_seed': amp}}, 'amp-noaug': {'high': {'per_seed': noaug}}}

    helped = paper_tables.augmentation_effect(summaries([0.95, 0.96, 0.94], [0.90, 0.92, 0.89]), 'high')
    assert helped.mean_points == pytest.approx(4.6667, abs=1e-3) and helped.seeds == 3
    assert helped.verdict() == 'the speed-ups helped'
    # The same gap on one seed and its reverse on another: the seeds disagree, so nothing is concluded.
    noisy = paper_tables.augmentation_effect(summaries([0.95, 0.90], [0.90, 0.95]), 'high')
    assert noisy.mean_points == pytest.approx(0.0) and noisy.verdict() == 'no difference beyond two standard errors'
    hurt = paper_tables.augmentation_effect(summaries([0.90, 0.91, 0.89], [0.95, 0.95, 0.94]), 'high')
    assert hurt.verdict() == 'the speed-ups hurt'
    single = paper_tables.augmentation_effect(summaries([0.9], [0.8]), 'high')
    assert single.standard_error_points is None and single.verdict() == 'one seed, no spread to judge it by'
