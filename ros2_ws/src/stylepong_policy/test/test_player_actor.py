"""The player's actors: ONNX and TorchScript give the same actions, the contract is checked in both, the
ONNX path needs no torch, and export writes the ONNX file with the contract in its metadata."""

import json
import os
import pathlib
import subprocess
import sys

import numpy as np
import onnx
import pytest
import torch

from stylepong_player import player_core
from stylepong_player.actor_contract import CONTRACT_KEYS, ActorMismatchError, current_spec_contract, onnx_path
from stylepong_policy.rl.export import export_actor, write_onnx_for
from stylepong_policy.rl.networks import ActorCritic

SHIPPED = pathlib.Path(__file__).resolve().parent.parent / 'models' / 'ppo_actor.pt'


def test_shipped_actor_onnx_and_torchscript_agree_on_random_observations():
    onnx_actor = player_core.load_actor(SHIPPED, 'onnx')
    torch_actor = player_core.load_actor(SHIPPED, 'torchscript')
    rng = np.random.default_rng(0)
    for scale in (0.1, 1.0, 5.0, 50.0):
        for _ in range(50):
            obs = (rng.normal(0, scale, (1, 26))).astype(np.float32)
            np.testing.assert_allclose(onnx_actor(obs), torch_actor(obs), atol=1e-5, rtol=0)


def test_shipped_onnx_carries_the_contract_of_the_sidecar():
    props = {p.key: json.loads(p.value) for p in onnx.load(str(onnx_path(SHIPPED))).metadata_props}
    sidecar = json.loads(SHIPPED.with_suffix('.json').read_text())
    for key in ('format', 'format_version', *CONTRACT_KEYS):
        assert props[key] == sidecar[key], key
    assert props['exported_from']['sha256'] == sidecar['actor_sha256']


@pytest.fixture
def exported(tmp_path):
    torch.manual_seed(0)
    contract = current_spec_contract()
    model = ActorCritic(contract['num_obs'], contract['num_obs'] + 5, contract['num_actions'], [32, 16], [16])
    model.obs_normalizer.update(torch.randn(300, contract['num_obs']) * 2.0 + 1.0)
    path, _ = export_actor(model, tmp_path / 'actor.pt', contract)
    return path, model


def test_export_writes_an_onnx_file_equal_to_the_model(exported):
    path, model = exported
    assert onnx_path(path).is_file()
    actor = player_core.load_actor(path, 'onnx')
    obs = torch.randn(1, 26) * 3
    with torch.no_grad():
        np.testing.assert_allclose(actor(obs.numpy()), model.act_deterministic(obs).numpy(), atol=1e-5)


def _rewrite_onnx_metadata(path: pathlib.Path, **changes) -> None:
    model = onnx.load(str(path))
    for prop in model.metadata_props:
        if prop.key in changes:
            prop.value = json.dumps(changes[prop.key])
    onnx.save(model, str(path))


@pytest.mark.parametrize(
    'key, value',
    [
        ('spec_version', 99),
        ('joint_names', ['a', 'b', 'c', 'd', 'e', 'f']),
        ('action_rate_hz', 50.0),
        ('obs_layout', [['joint_position_offset_rad', 6], ['other', 20]]),
    ],
)
def test_onnx_actor_with_another_contract_is_refused_in_one_line(exported, key, value):
    path, _ = exported
    _rewrite_onnx_metadata(onnx_path(path), **{key: value})
    with pytest.raises(ActorMismatchError, match=key) as error:
        player_core.load_actor(path, 'onnx')
    assert '\n' not in str(error.value)


def test_torchscript_actor_with_another_contract_is_refused_in_one_line(exported):
    path, _ = exported
    sidecar = path.with_suffix('.json')
    meta = json.loads(sidecar.read_text())
    meta['joint_names'] = list(reversed(meta['joint_names']))
    sidecar.write_text(json.dumps(meta))
    with pytest.raises(ActorMismatchError, match='joint_names') as error:
        player_core.load_actor(path, 'torchscript')
    assert '\n' not in str(error.value)


def test_missing_or_foreign_files_are_refused(tmp_path):
    with pytest.raises(ActorMismatchError, match='does not exist'):
        player_core.load_actor(tmp_path / 'none.pt', 'onnx')
    (tmp_path / 'junk.onnx').write_bytes(b'not a model')
    with pytest.raises(ActorMismatchError, match='not a loadable ONNX'):
        player_core.load_actor(tmp_path / 'junk.onnx', 'onnx')


def test_write_onnx_for_an_exported_actor(exported):
    path, _ = exported
    onnx_path(path).unlink()
    assert write_onnx_for(path) == onnx_path(path) and onnx_path(path).is_file()


def test_the_onnx_path_runs_without_torch():
    """The robot computer: torch cannot be imported at all, the player core and its ONNX actor still work."""
    code = (
        "import sys; sys.modules['torch'] = None\n"
        'import numpy as np\n'
        'from stylepong_player import player_core, spec\n'
        f"core = player_core.Player(player_core.PlayerConfig(), player_core.load_actor({str(SHIPPED)!r}, 'onnx'))\n"
        'core.set_enabled(True)\n'
        'core.on_joint_state(list(spec.JOINT_NAMES), list(spec.HOME_JOINT_POSITIONS_RAD), [0.0] * 6, 1.0)\n'
        "core.on_ball('world', 1.0, (-0.9, 0.1, 1.0), (-5.0, 0.0, 0.5), 1.0)\n"
        'result = core.step(1.0)\n'
        'assert result.policy and np.isfinite(result.command).all()\n'
        "assert 'torch' not in {m.split('.')[0] for m, v in sys.modules.items() if v is not None}\n"
        "print('ok')\n"
    )
    result = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True, env=dict(os.environ))
    assert result.returncode == 0 and 'ok' in result.stdout, result.stderr
