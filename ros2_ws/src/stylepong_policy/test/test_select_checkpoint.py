"""select_checkpoint on a tiny real run: 2 PPO iterations (64 envs, small networks, a numbered checkpoint
every iteration), then validation, append-only validation.csv, selection.json and the chosen actor; and
average_checkpoints on the same run."""

import csv
import json
import shutil
import subprocess
import sys

import pytest
import torch
from synthetic_reference import write_reference  # beside this file: conftest.py

from stylepong_policy.rl.export import load_actor
from stylepong_policy.training import average_checkpoints, select_checkpoint

TOY_CONFIG = """
policy: {actor_hidden_dims: [32, 32], critic_hidden_dims: [32, 32], init_noise_std: 1.0}
ppo: {num_steps_per_env: 8, num_learning_epochs: 1, num_mini_batches: 2, entropy_coef: 0.005}
runner: {iterations: 2, num_threads: 1, save_interval: 1, keep_checkpoints: 0, progress_bar: false}
task: {num_envs: 64}
"""
SELECT = ['--seeds', '1', '--first-seed', '900', '--balls', '8', '--high-first-seed', '950', '--high-seeds', '1']


@pytest.fixture(scope='module')
def run_dir(tmp_path_factory):
    root = tmp_path_factory.mktemp('select')
    (root / 'toy.yaml').write_text(TOY_CONFIG)
    run = root / 'run'
    result = subprocess.run(
        [
            sys.executable,
            '-m',
            'stylepong_policy.training.train',
            '--config',
            str(root / 'toy.yaml'),
            '--out',
            str(run),
            '--iterations',
            '2',
            '--num-envs',
            '64',
            '--no-tensorboard',
        ],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert result.returncode == 0, result.stdout + result.stderr
    assert [i for i, _ in select_checkpoint.numbered_checkpoints(run)] == [1, 2]
    return run


def read_csv(path):
    with path.open(newline='') as stream:
        return list(csv.DictReader(stream))


@pytest.mark.slow  # over 10 s on the 2-core machine: .ci/run runs it, `make test` skips it
def test_every_checkpoint_is_validated_once_and_rows_are_only_appended(run_dir, capsys):
    # A row someone validated earlier with another setting stays, first, untouched.
    earlier = {c: '' for c in select_checkpoint.COLUMNS}
    earlier.update(
        iteration='1',
        samples='512',
        val_success_all='0.5000',
        val_hit_rate_all='0.6000',
        speed='all',
        seeds='900-909',
        balls='200',
        checkpoint='checkpoints/model_000001.pt',
    )
    with (run_dir / select_checkpoint.CSV_NAME).open('w', newline='') as stream:
        writer = csv.DictWriter(stream, fieldnames=select_checkpoint.COLUMNS)
        writer.writeheader()
        writer.writerow(earlier)

    assert select_checkpoint.main(['--run', str(run_dir), *SELECT]) == 0
    rows = read_csv(run_dir / select_checkpoint.CSV_NAME)
    assert rows[0] == earlier
    new = rows[1:]
    assert [r['iteration'] for r in new] == ['1', '2']
    assert [r['checkpoint'] for r in new] == ['checkpoints/model_000001.pt', 'checkpoints/model_000002.pt']
    assert int(new[1]['samples']) == 2 * int(new[0]['samples']) > 0
    for row in new:
        assert (row['speed'], row['seeds'], row['balls'], row['high_seeds'], row['high_balls']) == (
            'all',
            '900-900',
            '8',
            '950-950',
            '8',
        )
        for key in ('val_success_all', 'val_success_high', 'val_hit_rate_all', 'val_hit_rate_high'):
            assert 0.0 <= float(row[key]) <= 1.0
    assert (run_dir / select_checkpoint.CURVE_NAME).stat().st_size > 0

    selection = json.loads((run_dir / select_checkpoint.SELECTION_NAME).read_text())
    chosen = select_checkpoint.choose(new)  # the earlier row's 0.5 was another setting: it is no candidate
    assert selection['iteration'] == int(chosen['iteration'])
    assert selection['checkpoint'] == chosen['checkpoint']
    assert selection['val_success_all'] == float(chosen['val_success_all'])
    assert selection['rule'] == select_checkpoint.RULE and selection['candidates'] == 2
    assert selection['validation']['seeds'] == [900] and selection['validation']['high_seeds'] == [950]

    # Again with the same setting: nothing is run, nothing is added.
    capsys.readouterr()
    assert select_checkpoint.main(['--run', str(run_dir), *SELECT]) == 0
    assert 'already validated' in capsys.readouterr().out
    assert read_csv(run_dir / select_checkpoint.CSV_NAME) == rows


def test_the_chosen_checkpoints_actor_is_exported_with_a_sidecar_naming_files_beside_it(run_dir, tmp_path):
    assert select_checkpoint.main(['--run', str(run_dir), *SELECT, '--export', str(run_dir / 'selected_actor.pt')]) == 0
    selection = json.loads((run_dir / select_checkpoint.SELECTION_NAME).read_text())
    actor = load_actor(run_dir / 'selected_actor.pt')
    training = actor.metadata['training']
    assert training['iterations'] == selection['iteration'] == training['selected_iteration']
    assert (run_dir / training['config']).is_file() and (run_dir / training['selection']).is_file()
    assert selection['exported_actor'] == 'selected_actor.pt'
    # Elsewhere, the sidecar names no file of the run directory.
    assert select_checkpoint.main(['--run', str(run_dir), *SELECT, '--export', str(tmp_path / 'actor.pt')]) == 0
    elsewhere = load_actor(tmp_path / 'actor.pt').metadata['training']
    assert 'config' not in elsewhere and 'selection' not in elsewhere
    assert not any(isinstance(v, str) and v.startswith('/') for v in elsewhere.values())


@pytest.mark.parametrize(
    'args',
    [
        ['--first-seed', '1000'],
        ['--first-seed', '995', '--seeds', '10'],
        ['--high-first-seed', '999', '--high-seeds', '2'],
    ],
)
def test_evaluation_seeds_are_refused(run_dir, args, capsys):
    with pytest.raises(SystemExit) as refused:
        select_checkpoint.main(['--run', str(run_dir), *args])
    assert refused.value.code == 2
    assert 'below 1000' in capsys.readouterr().err


def test_the_rule_prefers_success_then_high_speed_success_then_the_earlier_iteration():
    def row(iteration, success, high=''):
        return {'iteration': str(iteration), 'val_success_all': success, 'val_success_high': high}

    assert select_checkpoint.choose([row(1, '0.80'), row(2, '0.90'), row(3, '0.85')])['iteration'] == '2'
    rows = [row(1, '0.90', '0.70'), row(2, '0.90', '0.80'), row(3, '0.90', '0.75')]
    assert select_checkpoint.choose(rows)['iteration'] == '2'
    assert select_checkpoint.choose([row(4, '0.90', '0.80'), row(2, '0.90', '0.80')])['iteration'] == '2'


def test_a_csv_without_the_columns_is_left_alone(tmp_path, capsys):
    run = tmp_path / 'run'
    (run / 'checkpoints').mkdir(parents=True)
    (run / 'checkpoints' / 'model_000001.pt').write_bytes(b'')
    (run / select_checkpoint.CSV_NAME).write_text('iteration,samples,val_success_all\n5,100,0.9\n')
    assert select_checkpoint.main(['--run', str(run), '--seeds', '1']) == 2
    assert 'lacks the columns' in capsys.readouterr().err
    assert (run / select_checkpoint.CSV_NAME).read_text() == 'iteration,samples,val_success_all\n5,100,0.9\n'


def test_with_dtw_each_row_measures_the_strokes_and_the_style_rule_chooses_the_closest(run_dir, tmp_path):
    run = tmp_path / 'run'
    shutil.copytree(run_dir / 'checkpoints', run / 'checkpoints')  # a fresh validation.csv
    reference = str(write_reference(tmp_path / 'reference.npz'))
    setting = ['--seeds', '1', '--first-seed', '901', '--balls', '40', '--dtw', reference]
    assert select_checkpoint.main(['--run', str(run), *setting, '--min-success', '0.0']) == 0
    rows = read_csv(run / select_checkpoint.CSV_NAME)
    assert [r['iteration'] for r in rows] == ['1', '2'] and {r['dtw_dataset'] for r in rows} == {reference}
    for row in rows:
        assert all(float(row[f'val_dtw_{d}']) > 0.0 for d in select_checkpoint.DIRECTIONS)
    selection = json.loads((run / select_checkpoint.SELECTION_NAME).read_text())
    closest = min(rows, key=select_checkpoint.mean_dtw)
    assert selection['iteration'] == int(closest['iteration'])
    assert selection['rule'] == select_checkpoint.STYLE_RULE.format(min_success=0.0)
    assert selection['val_dtw_rad'] == {d: float(closest[f'val_dtw_{d}']) for d in select_checkpoint.DIRECTIONS}

    # A floor no checkpoint reaches: the success rule; the DTW rows are reused, nothing is run again.
    assert select_checkpoint.main(['--run', str(run), *setting, '--min-success', '1.0']) == 0
    assert read_csv(run / select_checkpoint.CSV_NAME) == rows
    selection = json.loads((run / select_checkpoint.SELECTION_NAME).read_text())
    assert selection['iteration'] == int(select_checkpoint.choose(rows)['iteration'])


def test_the_style_rule_takes_the_closest_strokes_among_checkpoints_that_return_enough():
    def row(iteration, success, dtw=('', '', '')):
        return {
            'iteration': str(iteration),
            'val_success_all': success,
            'val_success_high': '',
            **{f'val_dtw_{d}': v for d, v in zip(select_checkpoint.DIRECTIONS, dtw)},
        }

    rows = [
        row(1, '0.95', ('30', '40', '40')),
        row(2, '0.93', ('12', '18', '17')),
        row(3, '0.80', ('5', '5', '5')),
        row(4, '0.97'),
    ]
    # 3 is closer but returns too few; 4 was not measured.
    assert select_checkpoint.choose(rows, 0.93)['iteration'] == '2'
    # None qualifies with its distances: the success rule.
    assert select_checkpoint.choose(rows, 0.96)['iteration'] == '4'
    assert select_checkpoint.choose(rows)['iteration'] == '4'
    assert select_checkpoint.mean_dtw(rows[1]) == pytest.approx(47 / 3) and select_checkpoint.mean_dtw(rows[3]) is None


def test_the_worst_direction_rule_takes_the_checkpoint_whose_furthest_direction_is_closest_to_the_baseline():
    def row(iteration, success, dtw):
        return {
            'iteration': str(iteration),
            'val_success_all': success,
            'val_success_high': '',
            **{f'val_dtw_{d}': v for d, v in zip(select_checkpoint.DIRECTIONS, dtw)},
        }

    baseline = dict(zip(select_checkpoint.DIRECTIONS, (40.0, 50.0, 50.0)))
    rows = [
        row(1, '0.95', ('8', '15', '21')),  # mean 14.7, worst 21 / 50 = 0.42
        row(2, '0.95', ('14', '19', '19')),  # mean 17.3, worst 14 / 40 = 0.38 (forward)
        row(3, '0.90', ('4', '10', '10')),
    ]  # the closest, but returns too few
    assert select_checkpoint.choose(rows, 0.93)['iteration'] == '1'  # the style rule: the lowest mean
    assert select_checkpoint.choose(rows, 0.93, baseline)['iteration'] == '2'  # the worst-direction rule
    assert select_checkpoint.worst_ratio(rows[1], baseline) == pytest.approx(0.38)
    assert select_checkpoint.dtw_ratios(rows[0], baseline)['rightward'] == pytest.approx(0.42)


def test_the_worst_direction_rule_measures_the_baseline_on_the_same_balls(run_dir, tmp_path, capsys):
    run = tmp_path / 'run'
    shutil.copytree(run_dir / 'checkpoints', run / 'checkpoints')
    reference = str(write_reference(tmp_path / 'reference.npz'))
    baseline = tmp_path / 'baseline.pt'
    first = select_checkpoint.read_checkpoint(run / 'checkpoints' / 'model_000001.pt')
    select_checkpoint.export_checkpoint(first, baseline, onnx=False)
    setting = ['--seeds', '1', '--first-seed', '901', '--balls', '40', '--dtw', reference]
    assert (
        select_checkpoint.main(
            [
                '--run',
                str(run),
                *setting,
                '--min-success',
                '0.0',
                '--relative-to',
                str(baseline),
                '--from-iteration',
                '2',
            ]
        )
        == 0
    )
    rows = read_csv(run / select_checkpoint.CSV_NAME)
    assert [r['iteration'] for r in rows] == ['2']  # --from-iteration: 1 is not validated
    selection = json.loads((run / select_checkpoint.SELECTION_NAME).read_text())
    # The baseline is checkpoint 1's actor, measured on the same balls as the rows.
    validation = select_checkpoint.Setting('all', 901, 1, 40, None, 1, 40, reference)
    measured = select_checkpoint.baseline_distances(baseline, validation, 'cpu')
    assert selection['baseline'] == {'actor': str(baseline), 'val_dtw_rad': measured}
    assert selection['iteration'] == 2 and selection['rule'].startswith('lowest largest ratio')
    ratios = select_checkpoint.dtw_ratios(rows[0], measured)
    assert selection['val_dtw_ratio'] == {d: round(r, 4) for d, r in ratios.items()}
    with pytest.raises(SystemExit):
        select_checkpoint.main(['--run', str(run), *setting, '--relative-to', str(baseline)])  # needs --min-success
    assert '--relative-to needs --min-success' in capsys.readouterr().err


def test_a_csv_from_before_the_dtw_columns_is_extended_without_dtw_and_refused_with_it(tmp_path, run_dir, capsys):
    run = tmp_path / 'run'
    shutil.copytree(run_dir / 'checkpoints', run / 'checkpoints')
    with (run / select_checkpoint.CSV_NAME).open('w', newline='') as stream:
        csv.DictWriter(stream, fieldnames=select_checkpoint.COLUMNS).writeheader()
    before = (run / select_checkpoint.CSV_NAME).read_text()
    assert (
        select_checkpoint.main(
            [
                '--run',
                str(run),
                '--seeds',
                '1',
                '--balls',
                '4',
                '--dtw',
                str(write_reference(tmp_path / 'reference.npz')),
            ]
        )
        == 2
    )
    assert 'lacks the columns' in capsys.readouterr().err and (run / select_checkpoint.CSV_NAME).read_text() == before
    assert select_checkpoint.main(['--run', str(run), '--seeds', '1', '--balls', '4']) == 0
    assert [r['iteration'] for r in read_csv(run / select_checkpoint.CSV_NAME)] == ['1', '2']


@pytest.mark.parametrize(
    'args', [['--min-success', '0.9'], ['--dtw', 'missing.npz'], ['--dtw', __file__, '--min-success', '1.5']]
)
def test_the_style_rule_needs_a_dataset_and_a_rate(run_dir, args, capsys):
    with pytest.raises(SystemExit) as refused:
        select_checkpoint.main(['--run', str(run_dir), *args])
    assert refused.value.code == 2 and '--' in capsys.readouterr().err


# --- average_checkpoints: the weight average of a run's end, validated and shipped like a run ----------
def test_the_averaged_network_is_the_mean_of_the_checkpoints_with_the_last_ones_records(run_dir):
    first, last = (
        select_checkpoint.read_checkpoint(path) for _, path in select_checkpoint.numbered_checkpoints(run_dir)
    )
    averaged = average_checkpoints.average_checkpoints([first, last])
    for key, value in averaged['model'].items():
        assert torch.allclose(value, (first['model'][key] + last['model'][key]) / 2, atol=1e-6), key
    # The observation normaliser's statistics are averaged too: they are part of the policy.
    assert not torch.equal(averaged['model']['obs_normalizer.mean'], last['model']['obs_normalizer.mean'])
    assert (averaged['iteration'], averaged['env_steps'], averaged['wall_time_s']) == (
        last['iteration'],
        last['env_steps'],
        last['wall_time_s'],
    )
    assert averaged['optimizer'] is None and averaged['motion_prior'] is None
    assert averaged[select_checkpoint.AVERAGED_KEY] == [1, 2]
    wider = {**last, 'architecture': {**last['architecture'], 'actor_hidden_dims': [64, 64]}}
    with pytest.raises(ValueError, match='different networks'):
        average_checkpoints.average_checkpoints([first, wider])


def test_an_averaged_run_is_validated_and_exported_like_a_run_and_its_actor_names_what_it_averages(run_dir, tmp_path):
    out = tmp_path / 'averaged'
    assert average_checkpoints.main(['--run', str(run_dir), '--from-iteration', '1', '--out', str(out)]) == 0
    assert [i for i, _ in select_checkpoint.numbered_checkpoints(out)] == [2]
    assert json.loads((out / average_checkpoints.SUMMARY_NAME).read_text())['averaged_from'] == {
        'run': str(run_dir),
        'iterations': [1, 2],
    }
    assert (out / select_checkpoint.CONFIG_NAME).read_text() == (run_dir / select_checkpoint.CONFIG_NAME).read_text()
    assert select_checkpoint.main(['--run', str(out), *SELECT, '--export', str(out / 'actor.pt')]) == 0
    assert [r['iteration'] for r in read_csv(out / select_checkpoint.CSV_NAME)] == ['2']
    assert load_actor(out / 'actor.pt').metadata['training'][select_checkpoint.AVERAGED_KEY] == [1, 2]


def test_averaging_refuses_an_empty_range_and_an_occupied_directory(run_dir, tmp_path, capsys):
    assert (
        average_checkpoints.main(['--run', str(run_dir), '--from-iteration', '3', '--out', str(tmp_path / 'none')]) == 2
    )
    assert 'no numbered checkpoint between iterations 3 and its end' in capsys.readouterr().err
    assert (
        average_checkpoints.main(['--run', str(run_dir), '--from-iteration', '2', '--out', str(tmp_path / 'one')]) == 0
    )
    assert (
        average_checkpoints.main(['--run', str(run_dir), '--from-iteration', '1', '--out', str(tmp_path / 'one')]) == 2
    )
    assert 'already holds checkpoints' in capsys.readouterr().err
