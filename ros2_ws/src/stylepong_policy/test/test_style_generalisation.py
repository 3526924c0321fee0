"""style_generalisation on hand-made runs: a split, two finished held-out runs (one meets every target, one
misses), one missing, and a small style confusion JSON. The reports' targets are made by style_report's own
targets_record, the other files after their writers (learn_style's state, style_confusion's record)."""

import json
import pathlib

import pytest

from stylepong_policy.evaluation.strokes import DIRECTIONS
from stylepong_policy.evaluation.style_metrics import PHASES
from stylepong_policy.reports import style_generalisation as generalisation
from stylepong_policy.reports import style_report
from stylepong_policy.training import learn_style

SETTING = 'batched world, nominal (no randomisation, no sensing noise); seeds 1000-1009 x 200 balls; all speeds'
TUNING, HELDOUT = ['style_0', 'style_3'], ['style_1', 'style_2', 'style_4']  # style_4: no run
# Stage wall times adding up to an hour.
STAGE_SECONDS = dict(zip(learn_style.STAGES, (1.0, 5.0, 180.0, 3000.0, 150.0, 4.0, 240.0, 20.0)))
BLADE = {'ahead_m': 0.1, 'opening_deg': 30.0, 'facing_deg': 0.0, 'speed_m_s': 2.0, 'contacts': 10}


def write_split(folder: pathlib.Path) -> pathlib.Path:
    """split.json as tools/drawn_styles.py generate writes it (the style parameters cut short)."""
    folder.mkdir(parents=True, exist_ok=True)
    styles = {name: {'file': f'{name}.yaml', 'parameters': {}, 'rejected_draws': []} for name in TUNING + HELDOUT}
    split = {'seed': 1, 'count': 5, 'draws': 5, 'rejected': 0, 'tuning': TUNING, 'heldout': HELDOUT, 'styles': styles}
    path = folder / 'split.json'
    path.write_text(json.dumps(split, indent=2) + '\n')
    return path


def write_run(run: pathlib.Path, style_dtw: float, success: float, stages=learn_style.STAGES) -> None:
    """A learn_style run's learn_style.json (the given stages done) and, once its report stage is, report.json
    with style_report's targets: the new actor at style_dtw rad in every column, PPO at 3, the shipped at 2."""
    run.mkdir(parents=True)
    state = {
        'source': f'/data/sets/{run.name}',
        'minutes': 60.0,
        'device': 'cpu',
        'skill': None,
        'command': f'learn_style /data/sets/{run.name} --out {run}',
        'config': 'config/amp.yaml',
        'stages': {stage: {'wall_time_s': STAGE_SECONDS[stage]} for stage in stages},
    }
    (run / learn_style.STATE_NAME).write_text(json.dumps(state, indent=2) + '\n')
    if 'report' not in stages:
        return
    distances = {
        name: dict.fromkeys(style_report.COLUMNS, value)
        for name, value in (('style', style_dtw), ('ppo', 3.0), ('shipped', 2.0))
    }
    phases = {
        name: dict.fromkeys(style_report.COLUMNS, dict.fromkeys(PHASES, value / 3))
        for name, value in (('style', style_dtw), ('ppo', 3.0), ('shipped', 2.0))
    }
    blades = {actor: dict.fromkeys(DIRECTIONS, BLADE) for actor in ('style', style_report.DEMONSTRATIONS)}
    record = {
        'setting': SETTING,
        'dataset': 'dataset.npz',
        'success': {'style': {'all': success, 'high': 0.8}, 'ppo': {'all': 0.97, 'high': 0.9}},
        'dtw_rad': distances,
        'dtw_ratios': style_report.dtw_ratios(distances),
        'targets': style_report.targets_record(distances, phases, success, blades),
        'timings_s': {k: v['wall_time_s'] for k, v in state['stages'].items()},
        'notes': [],
    }
    (run / style_report.REPORT_JSON).write_text(json.dumps(record, indent=2) + '\n')


def write_confusion(path: pathlib.Path) -> pathlib.Path:
    """style_confusion.json as style_confusion.run writes it: the shipped set and two held-out ones, the
    shipped style actor and the two held-out runs' actors (style_1 nearest its own set, style_2 not)."""
    sets = ['shipped', 'style_1', 'style_2']
    overall = {
        'shipped': {'shipped': 0.40, 'style_1': 0.70, 'style_2': 0.80},
        'style_1': {'shipped': 0.60, 'style_1': 0.30, 'style_2': 0.50},
        'style_2': {'shipped': 0.45, 'style_1': 0.60, 'style_2': 0.55},
    }
    nearest = {'shipped': ('shipped', 0.30), 'style_1': ('style_1', 0.20), 'style_2': ('shipped', 0.10)}
    per_set = {'path': 'x', 'clips': 28, 'clips_per_label': {'forward': 3, 'leftward': 2, 'rightward': 2}}
    record = {
        'command': 'ros2 run stylepong_policy style_confusion --out runs/heldout/confusion',
        'generated': '2025-01-01',
        'setting': SETTING + '; deterministic actors',
        'baseline': 'ros2_ws/src/stylepong_policy/models/ppo_actor.pt',
        'actors': {name: {'path': f'runs/heldout/{name}/actor.pt', 'success_rate': 0.95} for name in overall},
        'baseline_success_rate': 0.97,
        'sets': {name: {**per_set, 'path': f'sets/{name}'} for name in sets},
        'dtw_rad': {
            name: {s: {**dict.fromkeys(DIRECTIONS, 10.0), 'overall': 10.0, 'strokes_compared': 2000} for s in sets}
            for name in [*overall, 'baseline']
        },
        'normalised': {
            name: {s: {**dict.fromkeys(DIRECTIONS, value), 'overall': value} for s, value in row.items()}
            for name, row in overall.items()
        },
        'verdicts': {
            name: {
                'nearest': best,
                'margin': margin,
                'margin_ratio': (overall[name][best] + margin) / overall[name][best],
                'own_set': name,
                'nearest_is_own': best == name,
            }
            for name, (best, margin) in nearest.items()
        },
        'dtw_call': 'dtw',
        'contacts': {'demonstrations': {}, 'actors': {}},
        'reports': {},
        'wall_time_s': 1200.0,
    }
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(record, indent=2) + '\n')
    return path


@pytest.fixture
def inputs(tmp_path):
    """The split, the runs (style_1 meets every target, style_2 misses, style_4 missing; a tuning style's
    run lies beside them) and the confusion JSON; returns run's argv and the output folder."""
    split = write_split(tmp_path / 'drawn')
    runs = tmp_path / 'runs'
    write_run(runs / 'style_1', style_dtw=1.0, success=0.95)
    write_run(runs / 'style_2', style_dtw=1.5, success=0.85)
    write_run(runs / 'style_0', style_dtw=1.0, success=0.95)  # tuning: never in the table
    confusion = write_confusion(tmp_path / 'confusion' / 'style_confusion.json')
    out = tmp_path / 'results'
    argv = ['--split', str(split), '--runs', str(runs), '--confusion', str(confusion), '--out', str(out)]
    return argv, out, runs


def written(out: pathlib.Path) -> tuple[str, dict]:
    return (out / generalisation.MARKDOWN_NAME).read_text(), json.loads((out / generalisation.JSON_NAME).read_text())


def table_line(text: str, name: str) -> str:
    return next(line for line in text.splitlines() if line.startswith(f'| `{name}` |'))


def test_a_row_per_heldout_set_with_its_targets_met_or_missed(inputs):
    argv, out, _ = inputs
    assert generalisation.run(argv) == 0
    text, record = written(out)
    assert list(record['heldout']) == HELDOUT
    met = table_line(text, 'style_1').split(' | ')
    assert met[1:4] == ['finished', '60.0', '95.0 %, met']
    assert met[4:6] == ['0.333, met', '0.500, met']  # overall: 1/3 of PPO's, 1/2 of the shipped actor's
    assert met[-1] == 'yes |'
    missed = table_line(text, 'style_2').split(' | ')
    assert missed[3:6] == ['85.0 %, missed', '0.500, missed', '0.750, missed']
    assert missed[-1] == 'no |'
    assert table_line(text, 'style_4').split(' | ')[1:3] == ['missing', '-']
    assert record['heldout']['style_4']['status'] == generalisation.MISSING
    assert record['heldout']['style_2']['ratios']['forward']['style / ppo'] == {
        'ratio': 0.5,
        'target': style_report.TARGET_RATIOS['style / ppo'],
        'met': False,
    }
    header = text.splitlines()[text.splitlines().index(table_line(text, 'style_1')) - 2]
    assert 'overall style / ppo (<= 0.40)' in header and 'rightward style / shipped (<= 0.65)' in header
    assert '**1 of 3 held-out sets met every target** (2 of 3 runs finished).' in text
    assert record['summary'] == {'sets': 3, 'finished': 2, 'met_every_target': 1}
    for name in TUNING:  # neither in the table nor anywhere else in the file
        assert name not in text and name not in record['heldout']


def test_the_confusion_matrix_is_copied_with_its_file_and_the_setting_is_stated(inputs):
    argv, out, _ = inputs
    generalisation.run(argv)
    text, record = written(out)
    confusion = argv[argv.index('--confusion') + 1]
    assert f'Copied from `{confusion}`' in text
    assert '| `style_1` | 0.600 | **0.300** | 0.500 | `style_1` | 1.67 |' in text
    assert '| `style_2` | **0.450** | 0.600 | 0.550 | `shipped` | 1.22 |' in text
    assert 'Held-out actors nearest their own set: 1 of 2 in the matrix.' in text
    assert 'Held-out sets not in the matrix: `style_4`.' in text
    assert record['confusion']['normalised']['style_2']['style_1'] == 0.60
    assert f'{SETTING} (style_1, style_2)' in text
    assert 'records no more of the machine): 60 min on cpu (style_1, style_2).' in text
    assert f'by `{record["command"]}`' in text
    assert record['command'].startswith('ros2 run stylepong_policy style_generalisation --split ')


def test_an_unfinished_run_and_a_report_without_targets_are_listed_as_such(inputs):
    argv, out, runs = inputs
    write_run(runs / 'style_4', style_dtw=1.0, success=0.95, stages=learn_style.STAGES[:4])
    report = runs / 'style_1' / style_report.REPORT_JSON
    report.write_text(json.dumps({k: v for k, v in json.loads(report.read_text()).items() if k != 'targets'}))
    assert generalisation.run(argv) == 0
    text, record = written(out)
    cells = table_line(text, 'style_4').split(' | ')
    assert cells[1:4] == ['unfinished (4 of 8 stages)', '53.1 so far', '-']
    assert cells[-1] == 'no |'
    cells = table_line(text, 'style_1').split(' | ')
    assert cells[1].startswith('finished; its report.json has no targets') and cells[3] == '-'
    assert cells[-1] == 'no |'
    assert record['summary'] == {'sets': 3, 'finished': 2, 'met_every_target': 0}


def test_the_looks_are_counted_once_per_change_of_the_heldout_figures(inputs):
    argv, out, runs = inputs
    assert generalisation.run(argv) == 0
    assert written(out)[1]['looks'] == 1
    assert 'Held-out sets looked at 1 time:' in written(out)[0]
    assert generalisation.run(argv) == 0  # the same figures again: not a new look
    assert written(out)[1]['looks'] == 1
    report = runs / 'style_2' / style_report.REPORT_JSON
    record = json.loads(report.read_text())
    record['targets']['success']['rate'] = 0.91
    report.write_text(json.dumps(record))
    assert generalisation.run(argv) == 0
    text, record = written(out)
    assert record['looks'] == 2 and 'Held-out sets looked at 2 times:' in text
    assert generalisation.run(argv) == 0
    assert written(out)[1]['looks'] == 2


@pytest.mark.parametrize(
    ('text', 'complaint'),
    [
        ('{"tuning": ["style_0"], "heldout": ', 'malformed, not the JSON tools/drawn_styles.py generate writes'),
        ('{"tuning": ["style_0"]}', "malformed, no lists of style names under 'heldout' and 'tuning'"),
        ('{"tuning": ["style_1"], "heldout": ["style_1"]}', 'style_1 is in both the tuning and the held-out half'),
    ],
)
def test_a_malformed_split_is_one_line_and_status_2(inputs, capsys, text, complaint):
    argv, out, _ = inputs
    split = pathlib.Path(argv[argv.index('--split') + 1])
    split.write_text(text)
    assert generalisation.run(argv) == 2
    error = capsys.readouterr().err
    assert error.count('\n') == 1 and error.startswith(f'style_generalisation: {split}: ') and complaint in error
    assert not out.exists()


def test_a_missing_split_or_malformed_confusion_is_one_line_and_status_2(inputs, capsys):
    argv, out, _ = inputs
    split = pathlib.Path(argv[argv.index('--split') + 1])
    confusion = pathlib.Path(argv[argv.index('--confusion') + 1])
    record = json.loads(confusion.read_text())
    del record['verdicts']
    confusion.write_text(json.dumps(record))
    assert generalisation.run(argv) == 2
    error = capsys.readouterr().err
    assert (
        error
        == f"style_generalisation: {confusion}: malformed, not the JSON style_confusion writes (no key 'verdicts')\n"
    )
    split.unlink()
    assert generalisation.run(argv) == 2
    assert capsys.readouterr().err == (
        f'style_generalisation: {split}: missing (tools/drawn_styles.py generate writes it)\n'
    )
    assert not out.exists()
