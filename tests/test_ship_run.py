"""ship_run (stylepong_policy.shipping.ship_run): what it copies into models/ and the summary it writes
(no training, no evaluation)."""

import json
import lzma
import pathlib

import numpy as np
import pytest
from PIL import Image

from stylepong_policy.rl.logger import read_progress
from stylepong_policy.shipping import ship_run

PROGRESS = 'iteration,success_rate\n1,0.25\n2,0.5\n'
# A chart's pixels as train leaves them: RGBA, more colours than a palette holds.
CURVE = np.dstack(
    [
        np.arange(48 * 64).reshape(48, 64) % 251,
        np.arange(48 * 64).reshape(48, 64) // 251,
        np.full((48, 64), 7),
        np.full((48, 64), 255),
    ]
).astype(np.uint8)


@pytest.fixture
def run_dir(tmp_path) -> pathlib.Path:
    """A run as train + select_checkpoint leave it, with placeholder contents."""
    run = tmp_path / 'run'
    (run / 'selected').mkdir(parents=True)
    (run / 'summary.json').write_text(json.dumps({'method': 'ppo', 'iterations': 1700, 'seed': 1}))
    (run / 'selection.json').write_text(json.dumps({'iteration': 1650, 'val_success_all': 0.95}))
    for name in ('config.yaml', 'validation.csv'):
        (run / name).write_text(f'contents of {name}')
    (run / 'progress.csv').write_text(PROGRESS)
    for name in ('learning_curve.png', 'validation_curve.png'):
        Image.fromarray(CURVE, mode='RGBA').save(run / name)
    for suffix in ('.pt', '.json', '.onnx'):
        (run / 'selected' / f'ppo_actor{suffix}').write_text(f'actor {suffix}')
    return run


def test_ship_copies_the_run_and_merges_the_selection_into_the_summary(run_dir, tmp_path):
    models = tmp_path / 'models'
    models.mkdir()
    written = ship_run.ship(run_dir, 'ppo', models)
    assert {p.name for p in written} == {
        'ppo_actor.pt',
        'ppo_actor.json',
        'ppo_actor.onnx',
        'ppo_config.yaml',
        'ppo_progress.csv.xz',
        'ppo_learning_curve.png',
        'ppo_validation.csv',
        'ppo_validation_curve.png',
        'ppo_summary.json',
    }
    assert (models / 'ppo_validation.csv').read_text() == 'contents of validation.csv'
    assert (models / 'ppo_actor.onnx').read_text() == 'actor .onnx'
    # The training log shipped compressed, read as it was; shipping it again gives the same bytes (no time in it).
    packed = (models / 'ppo_progress.csv.xz').read_bytes()
    assert lzma.decompress(packed).decode() == PROGRESS
    assert read_progress(models / 'ppo_progress.csv.xz') == {'iteration': [1.0, 2.0], 'success_rate': [0.25, 0.5]}
    ship_run.ship(run_dir, 'ppo', models)
    assert (models / 'ppo_progress.csv.xz').read_bytes() == packed
    # The curves shipped palettised.
    with Image.open(models / 'ppo_learning_curve.png') as curve:
        assert curve.mode == 'P' and curve.size == (64, 48)
    summary = json.loads((models / 'ppo_summary.json').read_text())
    assert summary['iterations'] == 1700 and summary['seed'] == 1
    assert summary['selection'] == {'iteration': 1650, 'val_success_all': 0.95}
    # Every file the summary names lies beside it.
    named = [
        summary[key] for key in ('actor', 'config', 'progress', 'learning_curve', 'validation', 'validation_curve')
    ]
    assert all((models / name).is_file() for name in named)


def test_ship_refuses_a_run_without_a_selected_actor(run_dir, tmp_path):
    (run_dir / 'selected' / 'ppo_actor.onnx').unlink()
    models = tmp_path / 'models'
    models.mkdir()
    with pytest.raises(FileNotFoundError, match='ppo_actor.onnx'):
        ship_run.ship(run_dir, 'ppo', models)
    assert not any(models.iterdir())


def test_evaluations_call_run_evaluation_and_record_the_command_that_repeats_them(tmp_path, monkeypatch):
    """evaluate_shipped evaluates in this process (no `ros2 run`): one run_evaluation per protocol entry,
    its summary written with the actor as the record names it and the `evaluate` command line."""
    from stylepong_policy.evaluation import evaluate

    calls = []

    def fake_run_evaluation(actor, **arguments):
        calls.append((pathlib.Path(actor), arguments))
        return {'success_rate': 0.5, 'actor': str(actor)}

    monkeypatch.setattr(evaluate, 'run_evaluation', fake_run_evaluation)
    written = ship_run.evaluate_shipped('ppo', tmp_path)
    assert [p.name for p in written] == ['ppo_eval_all.json', 'ppo_eval_high.json']
    assert calls == [(tmp_path / 'ppo_actor.pt', arguments) for arguments in ship_run.EVALUATIONS.values()]
    record = json.loads((tmp_path / 'ppo_eval_high.json').read_text())
    # Outside the repository only the file name is kept: no folder of this machine in a shipped record.
    assert record['actor'] == 'ppo_actor.pt'
    assert record['command'] == (
        'ros2 run stylepong_policy evaluate --actor ppo_actor.pt --seeds 10 --first-seed 2000 '
        '--balls 200 --speed high --json ppo_eval_high.json'
    )
