"""style_confusion on a tiny run (the shipped actors, one seed, a few balls, two sets), and its verdict rule."""
import json
import pathlib

import pytest
from synthetic_reference import write_reference

from stylepong_policy.evaluation import evaluate
from stylepong_policy.reports import style_confusion
from stylepong_policy.training.dataset import ReferenceDataset

PACKAGE = pathlib.Path(__file__).resolve().parents[1]
MODELS = PACKAGE / 'models'
SHIPPED_BAGS = PACKAGE.parents[1] / 'bags'
BALLS = 6
SEED = 1000


def test_verdict_is_the_smallest_normalised_distance_and_the_gap_to_the_next():
    result = style_confusion.verdict('long', {'long': 0.30, 'compact': 0.45, 'shipped': 0.60})
    assert result.nearest == 'long' and result.nearest_is_own and result.own_set == 'long'
    assert result.margin == pytest.approx(0.15) and result.margin_ratio == pytest.approx(1.5)
    other = style_confusion.verdict('compact', {'long': 0.30, 'compact': 0.45, 'shipped': None})
    assert other.nearest == 'long' and other.nearest_is_own is False
    alone = style_confusion.verdict('x', {'a': 0.5, 'b': None})
    assert alone.nearest == 'a' and alone.margin is None and alone.own_set is None and alone.nearest_is_own is None
    assert style_confusion.verdict('x', {'a': None}).nearest is None
    assert style_confusion.normalised(2.0, 4.0) == 0.5
    assert style_confusion.normalised(None, 4.0) is None and style_confusion.normalised(1.0, 0.0) is None


@pytest.fixture(scope='module')
def confusion(tmp_path_factory):
    folder = tmp_path_factory.mktemp('confusion')
    synthetic = write_reference(folder / 'synthetic.npz')
    argv = ['--actor', f'amp={MODELS / "amp_actor.pt"}', '--actor', f'ppo={MODELS / "ppo_actor.pt"}',
            '--set', f'shipped={SHIPPED_BAGS}', '--set', f'synthetic={synthetic}',
            '--baseline', str(MODELS / 'ppo_actor.pt'), '--seeds', '1', '--first-seed', str(SEED),
            '--balls', str(BALLS), '--num-threads', '1', '--out', str(folder / 'out')]
    assert style_confusion.run(argv) == 0
    return folder, json.loads((folder / 'out' / style_confusion.JSON_NAME).read_text())


def test_distances_are_evaluates_dtw_and_normalised_by_the_baseline(confusion):
    folder, record = confusion
    # evaluate --dtw on the same balls gives the same per-direction means for the synthetic set.
    summary = evaluate.run_evaluation(MODELS / 'amp_actor.pt', seeds=1, first_seed=SEED, balls=BALLS,
                                      dtw_dataset=folder / 'synthetic.npz')
    measured = record['dtw_rad']['amp']['synthetic']
    for direction, entry in summary['dtw'].items():
        assert measured[direction] == pytest.approx(entry['mean_rad'])
    weighted = sum(e['mean_rad'] * e['strokes'] for e in summary['dtw'].values() if e['strokes'])
    assert measured[style_confusion.OVERALL] == pytest.approx(weighted / BALLS)
    assert measured['strokes_compared'] == BALLS
    for actor in ('amp', 'ppo'):
        for name in ('shipped', 'synthetic'):
            baseline = record['dtw_rad'][style_confusion.BASELINE][name][style_confusion.OVERALL]
            expected = record['dtw_rad'][actor][name][style_confusion.OVERALL] / baseline
            assert record['normalised'][actor][name][style_confusion.OVERALL] == pytest.approx(expected)
    # The baseline's own file, evaluated once, is 1 everywhere; the style actor is nearer the clips.
    assert all(value[style_confusion.OVERALL] == 1.0 for value in record['normalised']['ppo'].values())
    assert record['normalised']['amp']['shipped'][style_confusion.OVERALL] < 0.7
    assert record['actors']['amp']['success_rate'] == summary['success_rate']
    assert record['sets']['shipped']['clips'] == 28
    assert record['sets']['shipped']['clips_per_label'] == {'forward': 3, 'leftward': 2, 'rightward': 2}


def test_outputs_name_each_actors_nearest_set(confusion):
    folder, record = confusion
    text = (folder / 'out' / style_confusion.MARKDOWN_NAME).read_text()
    for actor, v in record['verdicts'].items():
        row = {s: record['normalised'][actor][s][style_confusion.OVERALL] for s in record['sets']}
        assert v['nearest'] == min(row, key=row.get)
        assert f'| `{actor}` |' in text and f'`{v["nearest"]}`' in text
    assert (folder / 'out' / style_confusion.PNG_NAME).stat().st_size > 5_000
    assert '--set shipped=' in record['command'] and 'seed 1000 x 6 balls' in record['setting']
    # The blade at contact: every set's demonstrations (7 originals for the shipped clips), every actor's hits.
    blades = record['contacts']
    assert sum(m['contacts'] for m in blades['demonstrations']['shipped'].values() if m) == 7
    assert set(blades['actors']) == {'amp', 'ppo', style_confusion.BASELINE}
    assert '## The blade at contact' in text and '| `shipped` demonstrations | forward |' in text


def test_a_set_without_a_label_compares_only_the_strokes_it_has(tmp_path):
    dataset = ReferenceDataset.load(write_reference(tmp_path / 'all.npz'))
    keep = dataset.select(labels=['forward'])
    strokes = evaluate.evaluate_actor(MODELS / 'ppo_actor.pt', seeds=1, first_seed=SEED, balls=BALLS).strokes
    forward = dataset.with_clips(keep)
    distance = style_confusion.set_distance(strokes, forward)
    assert distance.strokes_compared == sum(s.direction == 'forward' for s in strokes)
    assert distance.by_direction_rad['leftward'] is None and distance.by_direction_rad['rightward'] is None
    assert distance.overall_rad == distance.by_direction_rad['forward']


@pytest.mark.parametrize('change, message', [
    (['--set', 'gone=/nowhere/bags'], 'set gone: /nowhere/bags does not exist'),
    (['--set', 'empty={empty}'], 'set empty: build_dataset found no usable clip'),
])
def test_a_set_that_gives_no_clips_exits_2_naming_it(tmp_path, capsys, change, message):
    (tmp_path / 'empty').mkdir()
    argv = ['--actor', f'ppo={MODELS / "ppo_actor.pt"}', '--baseline', str(MODELS / 'ppo_actor.pt'),
            '--out', str(tmp_path / 'out')] + [part.format(empty=tmp_path / 'empty') for part in change]
    assert style_confusion.run(argv) == 2
    assert message.format(empty=tmp_path / 'empty') in capsys.readouterr().err
    assert not (tmp_path / 'out').exists()


@pytest.mark.parametrize('argv', [
    ['--actor', 'a=x.pt', '--actor', 'a=y.pt', '--set', 's=d.npz', '--baseline', 'p.pt', '--out', 'o'],
    ['--actor', 'baseline=x.pt', '--set', 's=d.npz', '--baseline', 'p.pt', '--out', 'o'],
    ['--actor', 'no-equals-sign', '--set', 's=d.npz', '--baseline', 'p.pt', '--out', 'o'],
    ['--actor', 'a=x.pt', '--set', 's=d.npz', '--baseline', 'p.pt', '--out', 'o', '--balls', '0'],
])
def test_bad_arguments_exit_2(argv):
    with pytest.raises(SystemExit) as stopped:
        style_confusion.run(argv)
    assert stopped.value.code == 2
