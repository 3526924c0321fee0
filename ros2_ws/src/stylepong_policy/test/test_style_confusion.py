"""style_confusion on a tiny run (the shipped actors, one seed, a few balls, two sets), its verdict rule, and
the report it writes of an actor named like a set."""

import json
import pathlib

import numpy as np
import pytest
from PIL import Image
from synthetic_reference import write_reference

from stylepong_policy.evaluation import evaluate
from stylepong_policy.reports import style_confusion, style_report
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


def test_a_set_is_reported_when_an_actor_has_its_name_and_the_shipped_actor_is_there():
    assert style_confusion.reported_styles(['shipped', 'long', 'x'], ['shipped', 'long', 'lift']) == ['long']
    assert style_confusion.reported_styles(['long'], ['long']) == []


@pytest.fixture(scope='module')
def confusion(tmp_path_factory):
    """The shipped style actor twice: as exported and as its training checkpoint, the latter named like a set
    of forward clips alone (so that set gets a report, with one strip: each takes seconds); PPO too."""
    folder = tmp_path_factory.mktemp('confusion')
    synthetic = write_reference(folder / 'synthetic.npz')
    forward = write_reference(folder / 'forward.npz', labels=('forward',))
    actors = {
        'shipped': MODELS / 'amp_actor.pt',
        'ppo': MODELS / 'ppo_actor.pt',
        'forward': MODELS / 'amp_actor_checkpoint.pt',
    }
    sets = {'shipped': SHIPPED_BAGS, 'synthetic': synthetic, 'forward': forward}
    argv = [word for name, path in actors.items() for word in ('--actor', f'{name}={path}')]
    argv += [word for name, path in sets.items() for word in ('--set', f'{name}={path}')]
    argv += ['--baseline', str(MODELS / 'ppo_actor.pt'), '--seeds', '1', '--first-seed', str(SEED)]
    argv += ['--balls', str(BALLS), '--num-threads', '1', '--out', str(folder / 'out')]
    assert style_confusion.run(argv) == 0
    return folder, json.loads((folder / 'out' / style_confusion.JSON_NAME).read_text())


@pytest.mark.slow  # over 10 s on the 2-core machine: .ci/run runs it, `make test` skips it
def test_distances_are_evaluates_dtw_and_normalised_by_the_baseline(confusion):
    folder, record = confusion
    # evaluate --dtw on the same balls gives the same per-direction means for the synthetic set.
    summary = evaluate.run_evaluation(
        MODELS / 'amp_actor.pt', seeds=1, first_seed=SEED, balls=BALLS, dtw_dataset=folder / 'synthetic.npz'
    )
    measured = record['dtw_rad']['shipped']['synthetic']
    for direction, entry in summary['dtw'].items():
        assert measured[direction] == pytest.approx(entry['mean_rad'])
    weighted = sum(e['mean_rad'] * e['strokes'] for e in summary['dtw'].values() if e['strokes'])
    assert measured[style_confusion.OVERALL] == pytest.approx(weighted / BALLS)
    assert measured['strokes_compared'] == BALLS
    for actor in ('shipped', 'ppo'):
        for name in ('shipped', 'synthetic', 'forward'):
            baseline = record['dtw_rad'][style_confusion.BASELINE][name][style_confusion.OVERALL]
            expected = record['dtw_rad'][actor][name][style_confusion.OVERALL] / baseline
            assert record['normalised'][actor][name][style_confusion.OVERALL] == pytest.approx(expected)
    # The baseline's own file, evaluated once, is 1 everywhere; the style actor is nearer the clips.
    assert all(value[style_confusion.OVERALL] == 1.0 for value in record['normalised']['ppo'].values())
    assert record['normalised']['shipped']['shipped'][style_confusion.OVERALL] < 0.7
    assert record['actors']['shipped']['success_rate'] == summary['success_rate']
    # The checkpoint given as an actor is exported to the same function: the same strokes to the last bit.
    assert record['dtw_rad']['forward'] == record['dtw_rad']['shipped']
    assert record['actors']['forward']['success_rate'] == summary['success_rate']
    assert record['sets']['shipped']['clips'] == 28
    assert record['sets']['shipped']['clips_per_label'] == {'forward': 3, 'leftward': 2, 'rightward': 2}


def test_outputs_name_each_actors_nearest_set(confusion):
    folder, record = confusion
    text = (folder / 'out' / style_confusion.MARKDOWN_NAME).read_text()
    for actor, v in record['verdicts'].items():
        row = {s: record['normalised'][actor][s][style_confusion.OVERALL] for s in record['sets']}
        assert row[v['nearest']] == min(row.values())  # PPO's row ties at 1 everywhere: any of those
        assert f'| `{actor}` |' in text and f'`{v["nearest"]}`' in text
    assert (folder / 'out' / style_confusion.PNG_NAME).stat().st_size > 5_000
    assert '--set shipped=' in record['command'] and 'seed 1000 x 6 balls' in record['setting']
    # The blade at contact: every set's demonstrations (7 originals for the shipped clips), every actor's hits.
    blades = record['contacts']
    assert sum(m['contacts'] for m in blades['demonstrations']['shipped'].values() if m) == 7
    assert set(blades['actors']) == {'shipped', 'ppo', 'forward', style_confusion.BASELINE}
    assert '## The blade at contact' in text and '| `shipped` demonstrations | forward |' in text


def test_an_actor_named_like_a_set_gets_its_report_and_onnx_from_the_same_evaluations(confusion):
    folder, record = confusion
    styles = folder / 'out' / style_confusion.STYLES_DIR
    assert sorted(p.name for p in styles.iterdir()) == ['forward']  # not the shipped actor's own set
    assert record['reports'] == {'forward': {'report': 'styles/forward/report.md', 'onnx': 'styles/forward/actor.onnx'}}
    assert '[`forward`](styles/forward/report.md)' in (folder / 'out' / style_confusion.MARKDOWN_NAME).read_text()
    report = json.loads((styles / 'forward' / style_report.REPORT_JSON).read_text())
    # Its figures are the matrix's: the style actor's, the baseline's as PPO's, the shipped actor's.
    assert report['success'] == {
        'style': {'all': record['actors']['forward']['success_rate'], 'high': None},
        'ppo': {'all': record['baseline_success_rate'], 'high': None},
        'shipped': {'all': record['actors']['shipped']['success_rate'], 'high': None},
    }
    for role, actor in (('style', 'forward'), ('ppo', style_confusion.BASELINE)):
        for column, value in report['dtw_rad'][role].items():
            assert value == pytest.approx(record['dtw_rad'][actor]['forward'][column])
    assert all(v == pytest.approx(1.0) for v in report['dtw_ratios']['style / shipped'].values() if v is not None)
    # No record lies beside the checkpoint: the report says so and has no run section.
    text = (styles / 'forward' / style_report.REPORT_MD).read_text()
    assert 'No record of how it was learned' in text and '## The run' not in text
    assert '`ros2 run stylepong_policy style_confusion --actor shipped=' in text
    # Every chart small: a palette image.
    pictures = sorted((styles / 'forward').glob('*.png'))
    assert {style_report.SUCCESS_PNG, style_report.DTW_PNG, style_report.SMOOTHNESS_PNG} <= {p.name for p in pictures}
    for picture in pictures:
        with Image.open(picture) as image:
            assert image.mode == 'P', picture.name
    assert [strip['direction'] for strip in report['strips']] == ['forward']  # the set's one label
    for strip in report['strips']:
        assert strip['strip'] or strip['strip_missing']
        assert f']({strip["strip"] or strip["joints"]})' in text


def test_the_onnx_actor_written_beside_a_report_acts_as_the_actor(confusion):
    import onnxruntime
    import torch

    from stylepong_player.actor_contract import ONNX_INPUT, ONNX_OUTPUT, parse_onnx_metadata
    from stylepong_policy.rl.export import file_sha256, load_actor

    folder, _ = confusion
    path = folder / 'out' / style_confusion.STYLES_DIR / 'forward' / style_confusion.ONNX_NAME
    session = onnxruntime.InferenceSession(str(path), providers=['CPUExecutionProvider'])
    metadata = parse_onnx_metadata(session.get_modelmeta().custom_metadata_map, path)
    # It names the checkpoint it came from, not the temporary export.
    checkpoint = MODELS / 'amp_actor_checkpoint.pt'
    assert metadata['exported_from'] == {'file': checkpoint.name, 'sha256': file_sha256(checkpoint)}
    observations = np.random.default_rng(0).normal(0.0, 2.0, (16, metadata['num_obs'])).astype(np.float32)
    with torch.no_grad():
        expected = load_actor(MODELS / 'amp_actor.pt').module(torch.from_numpy(observations)).numpy()
    got = session.run([ONNX_OUTPUT], {ONNX_INPUT: observations})[0]
    assert np.abs(got - expected).max() < 1e-5


def test_the_run_section_comes_from_the_record_beside_the_actor(tmp_path):
    """ship_skill's <name>.json beside a skill, learn_style.json beside a run's actor.pt; an exported
    actor's sidecar is no such record."""
    shipped = style_confusion.learned_record(MODELS / 'skills' / 'compact.pt')
    assert shipped is not None and shipped[0] == MODELS / 'skills' / 'compact.json'
    assert shipped[1]['command'].startswith('learn_style demonstrations/compact ')
    assert {'train', 'choose'} <= set(shipped[1]['stages']) and 'learned_on' not in shipped[1]['stages']
    run = tmp_path / 'run'
    run.mkdir()
    (run / 'actor.pt').write_bytes(b'')
    (run / 'learn_style.json').write_text(
        json.dumps(
            {'command': 'learn_style bags --out run', 'skill': 'start.pt', 'stages': {'train': {'wall_time_s': 60.0}}}
        )
    )
    assert style_confusion.learned_record(run / 'actor.pt') == (
        run / 'learn_style.json',
        {
            'command': 'learn_style bags --out run',
            'started_from': 'start.pt',
            'stages': {'train': {'wall_time_s': 60.0}},
        },
    )
    assert style_confusion.learned_record(MODELS / 'amp_actor.pt') is None


def test_a_set_without_a_label_compares_only_the_strokes_it_has(tmp_path):
    dataset = ReferenceDataset.load(write_reference(tmp_path / 'all.npz'))
    keep = dataset.select(labels=['forward'])
    strokes = evaluate.evaluate_actor(MODELS / 'ppo_actor.pt', seeds=1, first_seed=SEED, balls=BALLS).strokes
    forward = dataset.with_clips(keep)
    distance = style_confusion.set_distance(strokes, forward)
    assert distance.strokes_compared == sum(s.direction == 'forward' for s in strokes)
    assert distance.by_direction_rad['leftward'] is None and distance.by_direction_rad['rightward'] is None
    assert distance.overall_rad == distance.by_direction_rad['forward']


@pytest.mark.parametrize(
    'change, message',
    [
        (['--set', 'gone=/nowhere/bags'], 'set gone: /nowhere/bags does not exist'),
        (['--set', 'empty={empty}'], 'set empty: build_dataset found no usable clip'),
    ],
)
def test_a_set_that_gives_no_clips_exits_2_naming_it(tmp_path, capsys, change, message):
    (tmp_path / 'empty').mkdir()
    argv = [
        '--actor',
        f'ppo={MODELS / "ppo_actor.pt"}',
        '--baseline',
        str(MODELS / 'ppo_actor.pt'),
        '--out',
        str(tmp_path / 'out'),
    ] + [part.format(empty=tmp_path / 'empty') for part in change]
    assert style_confusion.run(argv) == 2
    assert message.format(empty=tmp_path / 'empty') in capsys.readouterr().err
    assert not (tmp_path / 'out').exists()


@pytest.mark.parametrize(
    'argv',
    [
        ['--actor', 'a=x.pt', '--actor', 'a=y.pt', '--set', 's=d.npz', '--baseline', 'p.pt', '--out', 'o'],
        ['--actor', 'baseline=x.pt', '--set', 's=d.npz', '--baseline', 'p.pt', '--out', 'o'],
        ['--actor', 'no-equals-sign', '--set', 's=d.npz', '--baseline', 'p.pt', '--out', 'o'],
        ['--actor', 'a=x.pt', '--set', 's=d.npz', '--baseline', 'p.pt', '--out', 'o', '--balls', '0'],
    ],
)
def test_bad_arguments_exit_2(argv):
    with pytest.raises(SystemExit) as stopped:
        style_confusion.run(argv)
    assert stopped.value.code == 2
