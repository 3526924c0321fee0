"""The skill library: demonstrations' fingerprints, the lineage a learned skill keeps, and which skills are
offered as the start for a set."""

import dataclasses

import numpy as np
import pytest
import torch
from synthetic_reference import write_reference

from stylepong_policy.training import skills
from stylepong_policy.training.dataset import ReferenceDataset


@pytest.fixture
def dataset(tmp_path) -> ReferenceDataset:
    return ReferenceDataset.load(write_reference(tmp_path / 'reference.npz'))


def test_a_fingerprint_is_the_original_clips_whatever_their_speed_ups(dataset):
    originals = dataset.with_clips(dataset.select(speed_factors=[1]))
    assert skills.demonstrations_fingerprint(originals) == skills.demonstrations_fingerprint(dataset)


def test_a_fingerprint_ignores_float_noise_and_sees_a_moved_pose_or_a_relabelled_clip(dataset):
    before = skills.demonstrations_fingerprint(dataset)
    noisy = dataclasses.replace(dataset, q=dataset.q + 1e-9)
    assert skills.demonstrations_fingerprint(noisy) == before
    moved = dataset.q.copy()
    moved[int(dataset.clip_start[0]) + 10, 2] += 0.01
    assert skills.demonstrations_fingerprint(dataclasses.replace(dataset, q=moved)) != before
    label = dataset.label.copy()
    label[0] = 'rightward' if label[0] != 'rightward' else 'leftward'
    assert skills.demonstrations_fingerprint(dataclasses.replace(dataset, label=label)) != before


def test_a_learned_skill_keeps_its_starts_demonstrations_and_its_own_once():
    assert skills.lineage_after({}, 'a') == ['a']
    assert skills.lineage_after({skills.LINEAGE_KEY: ['a']}, 'b') == ['a', 'b']
    assert skills.lineage_after({skills.LINEAGE_KEY: ['a', 'b']}, 'a') == ['a', 'b']


def test_the_library_is_the_shipped_skill_then_the_learned_ones_and_a_set_is_not_offered_its_own(tmp_path):
    (tmp_path / skills.LIBRARY_DIR).mkdir()
    torch.save({'model': {}, skills.LINEAGE_KEY: ['c', 'w']}, tmp_path / skills.LIBRARY_DIR / 'wristy.pt')
    torch.save({'model': {}, skills.LINEAGE_KEY: ['c']}, tmp_path / skills.LIBRARY_DIR / 'compact.pt')
    library = skills.library(tmp_path)
    assert [s.name for s in library] == [skills.SHIPPED, 'compact', 'wristy']
    assert library[0].path == tmp_path / skills.SHIPPED_FILE and library[2].learned_on == ('c', 'w')
    assert [s.name for s in skills.offered(library, 'w')] == [skills.SHIPPED, 'compact']
    assert [s.name for s in skills.offered(library, 'c')] == [skills.SHIPPED]
    assert [s.name for s in skills.offered(library, 'new')] == [skills.SHIPPED, 'compact', 'wristy']


def test_the_shipped_library_holds_networks_of_the_recipes_sizes_each_with_its_demonstrations():
    from stylepong_policy.training.learn_style import models_dir

    library = {s.name: s for s in skills.library(models_dir())}
    from stylepong_policy.rl.networks import ActorCritic, fit_value_streams, network_sizes

    shipped = torch.load(library[skills.SHIPPED].path, map_location='cpu', weights_only=False)
    # A run of the recipe: its critic has a value stream for the free follow-through.
    run = ActorCritic(**shipped['architecture'], value_streams=2)
    for name, skill in library.items():
        checkpoint = torch.load(skill.path, map_location='cpu', weights_only=False)
        assert network_sizes(checkpoint['architecture']) == shipped['architecture'], name
        run.load_state_dict(fit_value_streams(checkpoint['model'], checkpoint['architecture'], 2))
        assert name == skills.SHIPPED or len(skill.learned_on) >= 1
        assert np.all([len(f) == 16 for f in skill.learned_on])
