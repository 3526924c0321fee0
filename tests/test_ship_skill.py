"""ship_skill (stylepong_policy.shipping.ship_skill): a learn_style run's network into the skill library, with
the demonstrations behind it (through the runs it started from) and how its config differed from the recipe
(no training)."""

import json
import pathlib

import numpy as np
import pytest
import torch
import yaml

from stylepong_policy.shipping import ship_skill
from stylepong_policy.training import learn_style, skills
from stylepong_policy.training.dataset import Clip, SourceClip, assemble_dataset
from stylepong_policy.training.train import default_config_path


def fake_run(run: pathlib.Path, start: pathlib.Path, swing_rad: float, config: dict) -> pathlib.Path:
    """A finished learn_style run as its files leave it: state, dataset (one forward clip), config, network."""
    from stylepong_description.robot_model import JOINT_NAMES

    t = np.arange(60) / 60.0
    q = np.zeros((60, 6)) + swing_rad * np.sin(np.pi * t)[:, None]
    dataset = assemble_dataset(
        [SourceClip(Clip(t=t, q=q, qd=np.gradient(q, t, axis=0)), 'forward', 'fake')], (2,), JOINT_NAMES, 60.0
    )
    paths = learn_style.paths_of(run)
    paths.train.mkdir(parents=True)
    dataset.save(paths.dataset)
    (paths.train / 'config.yaml').write_text(yaml.safe_dump(config))
    torch.save({'model': {}, 'architecture': {}, 'optimizer': None}, paths.actor_checkpoint)
    learn_style.write_state(
        paths,
        {
            'source': str(run / 'bags'),
            'skill': str(start),
            'command': 'learn_style ...',
            'stages': {'train': {'iterations': 3}, 'export': {}},
        },
    )
    return run


@pytest.fixture
def recipe() -> dict:
    return yaml.safe_load(default_config_path('amp').read_text())


def test_a_skill_carries_its_starts_demonstrations_and_its_differences_from_the_recipe(tmp_path, recipe):
    shipped = tmp_path / 'shipped.pt'
    torch.save({'model': {}, 'architecture': {}}, shipped)
    first = fake_run(tmp_path / 'first', shipped, 0.3, recipe)
    changed = {**recipe, 'amp': {**recipe['amp'], 'hold_success_margin': 0.05, 'dataset': 'elsewhere.npz'}}
    second = fake_run(tmp_path / 'second', first / learn_style.ACTOR_CHECKPOINT_NAME, 0.5, changed)
    models = tmp_path / 'models'
    written = ship_skill.ship_skill(second, 'second', models)
    assert [p.name for p in written] == ['second.pt', 'second.json']
    fingerprints = [learn_style.fingerprint_of(learn_style.paths_of(run)) for run in (first, second)]
    library = skills.library(models)
    assert [(s.name, s.learned_on) for s in library[1:]] == [('second', tuple(fingerprints))]
    record = json.loads((models / skills.LIBRARY_DIR / 'second.json').read_text())
    assert record['learned_on'] == fingerprints and record['train'] == {'iterations': 3}
    assert record['recipe_differences'] == {'amp.hold_success_margin': [0.05, recipe['amp']['hold_success_margin']]}


def test_an_unfinished_run_is_refused_in_one_line(tmp_path, capsys):
    run = tmp_path / 'run'
    run.mkdir()
    learn_style.write_state(learn_style.paths_of(run), {'stages': {'train': {}}})
    assert ship_skill.main(['--run', str(run), '--name', 'x', '--models-dir', str(tmp_path)]) == 2
    assert capsys.readouterr().err.count('\n') == 1
