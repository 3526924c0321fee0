"""The exported actor: TorchScript equals the training model, the sidecar guards the spec contract."""

import json

import pytest
import torch

from stylepong_policy.rl.export import ActorMismatchError, current_spec_contract, export_actor, load_actor, sidecar_path
from stylepong_policy.rl.networks import ActorCritic

CONTRACT = {
    'spec_version': 3,
    'action_rate_hz': 60.0,
    'joint_names': ['j1', 'j2'],
    'obs_layout': [['joint_positions', 2], ['ball_position', 3]],
    'num_obs': 5,
    'num_actions': 2,
    'action_decoding': {'scale_rad': [0.5, 0.5]},
}


@pytest.fixture
def trained_model():
    torch.manual_seed(0)
    model = ActorCritic(5, 9, 2, [32, 16], [16])
    # Statistics far from (0, 1), so a normaliser left out of the export would show.
    model.obs_normalizer.update(torch.randn(500, 5) * torch.tensor([0.1, 3.0, 10.0, 0.5, 2.0]) + 4.0)
    return model


def test_exported_actor_equals_the_model_with_its_normaliser(tmp_path, trained_model):
    path, json_path = export_actor(trained_model, tmp_path / 'actor.pt', CONTRACT, training={'seed': 7})
    assert json_path == sidecar_path(path) == tmp_path / 'actor.json'
    actor = load_actor(path, expected=CONTRACT)
    obs = torch.randn(64, 5) * 5.0 + 4.0
    with torch.no_grad():
        torch.testing.assert_close(actor(obs), trained_model.act_deterministic(obs))
        without_norm = trained_model.actor(obs)
    assert not torch.allclose(actor(obs), without_norm, atol=1e-3)
    meta = json.loads(json_path.read_text())
    assert meta['training'] == {'seed': 7} and meta['joint_names'] == ['j1', 'j2']
    assert actor.num_obs == 5 and actor.num_actions == 2
    # The training model is untouched by export (still trainable, still on its device).
    assert trained_model.training and trained_model.std.requires_grad


@pytest.mark.parametrize(
    'key, value',
    [
        ('spec_version', 4),
        ('joint_names', ['j2', 'j1']),
        ('action_rate_hz', 50.0),
        ('obs_layout', [['joint_positions', 2], ['ball_velocity', 3]]),
        ('action_decoding', {'scale_rad': [0.4, 0.5]}),
    ],
)
def test_loader_refuses_a_different_spec(tmp_path, trained_model, key, value):
    path, _ = export_actor(trained_model, tmp_path / 'actor.pt', CONTRACT)
    with pytest.raises(ActorMismatchError, match=key):
        load_actor(path, expected={**CONTRACT, key: value})


def test_loader_refuses_missing_or_altered_files(tmp_path, trained_model):
    path, json_path = export_actor(trained_model, tmp_path / 'actor.pt', CONTRACT)
    other, _ = export_actor(ActorCritic(5, 9, 2, [8], [8]), tmp_path / 'other.pt', CONTRACT)
    path.write_bytes(other.read_bytes())  # a different actor under the sidecar of the first
    with pytest.raises(ActorMismatchError, match='SHA-256'):
        load_actor(path, expected=CONTRACT)
    json_path.unlink()
    with pytest.raises(ActorMismatchError, match='no sidecar'):
        load_actor(path, expected=CONTRACT)
    with pytest.raises(ActorMismatchError, match='does not exist'):
        load_actor(tmp_path / 'missing.pt', expected=CONTRACT)


def test_export_refuses_a_network_that_does_not_fit_the_spec(tmp_path):
    with pytest.raises(ActorMismatchError, match='inputs'):
        export_actor(ActorCritic(6, 9, 2, [8], [8]), tmp_path / 'a.pt', CONTRACT)


def test_current_spec_contract_describes_the_spec_module():
    from stylepong_player import spec

    contract = current_spec_contract()
    assert contract['spec_version'] == spec.SPEC_VERSION
    assert contract['joint_names'] == list(spec.JOINT_NAMES)
    assert contract['num_obs'] == sum(size for _, size in spec.OBS_LAYOUT)
    assert contract['action_rate_hz'] == 60.0
    json.dumps(contract)  # the sidecar must be able to hold it
