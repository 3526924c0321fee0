"""Export the actor for deployment: TorchScript with the observation normaliser inside, plus a sidecar JSON.

The TorchScript file maps the raw observation vector of the spec module to the mean action (the raw
policy output the spec module decodes into joint position targets). The sidecar `<name>.json` says
which spec it was trained against (spec version, rates, joint names, observation layout, action
decoding parameters) and carries the file's SHA-256, so a player refuses an actor built for a
different observation/action contract instead of silently feeding it the wrong numbers.
"""
from __future__ import annotations

import contextlib
import copy
import hashlib
import json
import os
import pathlib
import warnings
from dataclasses import dataclass
from typing import Any

import torch
from torch import nn

from .networks import ActorCritic

SIDECAR_FORMAT = 'stylepong-actor'
SIDECAR_VERSION = 1
# The contract between an actor and whoever runs it: all must match exactly for an actor to load.
CONTRACT_KEYS = ('spec_version', 'action_rate_hz', 'joint_names', 'obs_layout', 'num_obs', 'num_actions',
                 'action_decoding')


class ActorMismatchError(ValueError):
    """The actor file does not fit the running code's observation/action spec (or is damaged)."""


class DeployedActor(nn.Module):
    """Raw observations [B, num_obs] -> mean actions [B, num_actions]."""

    def __init__(self, normalizer: nn.Module, actor: nn.Module):
        super().__init__()
        self.normalizer = normalizer
        self.actor = actor

    def forward(self, obs: torch.Tensor) -> torch.Tensor:
        return self.actor(self.normalizer(obs))


@contextlib.contextmanager
def _quiet_torchscript():
    """torch 2.13 flags torch.jit as deprecated in favour of torch.export; TorchScript is still what a
    Python or libtorch player loads in one call, so only that warning is silenced, only here."""
    with warnings.catch_warnings():
        warnings.filterwarnings('ignore', message=r'`torch\.jit\.', category=DeprecationWarning)
        yield


@dataclass
class LoadedActor:
    module: torch.jit.ScriptModule
    metadata: dict[str, Any]
    path: pathlib.Path

    @property
    def num_obs(self) -> int:
        return int(self.metadata['num_obs'])

    @property
    def num_actions(self) -> int:
        return int(self.metadata['num_actions'])

    def __call__(self, obs: torch.Tensor) -> torch.Tensor:
        return self.module(obs)


def sidecar_path(actor_path: str | pathlib.Path) -> pathlib.Path:
    return pathlib.Path(actor_path).with_suffix('.json')


def _jsonable(value: Any) -> Any:
    """Tuples to lists and numpy/torch scalars to numbers, so a round trip through JSON compares equal."""
    if isinstance(value, dict):
        return {str(k): _jsonable(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_jsonable(v) for v in value]
    if hasattr(value, 'tolist'):
        return _jsonable(value.tolist())
    return value


def current_spec_contract() -> dict[str, Any]:
    """The running code's observation/action contract, read from `stylepong_policy.spec`."""
    from stylepong_policy import spec
    layout = [[str(name), int(size)] for name, size in spec.OBS_LAYOUT]
    return _jsonable({'spec_version': spec.SPEC_VERSION, 'action_rate_hz': float(spec.ACTION_RATE_HZ),
                      'joint_names': list(spec.JOINT_NAMES), 'obs_layout': layout,
                      'num_obs': spec.NUM_OBS, 'num_actions': spec.NUM_ACTIONS,
                      'action_decoding': spec.action_decoding()})


def file_sha256(path: str | pathlib.Path) -> str:
    digest = hashlib.sha256()
    with open(path, 'rb') as f:
        for chunk in iter(lambda: f.read(1 << 20), b''):
            digest.update(chunk)
    return digest.hexdigest()


def build_deployed_actor(actor_critic: ActorCritic) -> torch.jit.ScriptModule:
    """Script + freeze a CPU copy of the actor and its normaliser (the training model is left untouched)."""
    normalizer = (copy.deepcopy(actor_critic.obs_normalizer) if actor_critic.normalize_observations
                  else nn.Identity())
    module = DeployedActor(normalizer, copy.deepcopy(actor_critic.actor)).cpu().eval()
    # Freezing folds weights and normaliser statistics into constants: the file is self-contained.
    with _quiet_torchscript():
        return torch.jit.freeze(torch.jit.script(module))


def export_actor(actor_critic: ActorCritic, path: str | pathlib.Path, contract: dict[str, Any],
                 training: dict[str, Any] | None = None) -> tuple[pathlib.Path, pathlib.Path]:
    """Write the TorchScript actor at `path` and its sidecar JSON beside it; returns both paths."""
    path = pathlib.Path(path)
    contract = _jsonable(contract)
    missing = [k for k in CONTRACT_KEYS if k not in contract]
    if missing:
        raise ValueError(f'contract lacks {missing}')
    if (contract['num_obs'], contract['num_actions']) != (actor_critic.num_obs, actor_critic.num_actions):
        raise ActorMismatchError(
            f'the network has {actor_critic.num_obs} inputs and {actor_critic.num_actions} outputs, the spec says '
            f'{contract["num_obs"]} and {contract["num_actions"]}')
    deployed = build_deployed_actor(actor_critic)
    # The scripted copy must compute exactly what the training model's deterministic action is.
    probe = torch.randn(8, actor_critic.num_obs)
    with torch.no_grad():
        expected = actor_critic.act_deterministic(probe.to(next(actor_critic.parameters()).device)).cpu()
        got = deployed(probe)
    if not torch.allclose(got, expected, atol=1e-5, rtol=1e-5):
        raise RuntimeError('the exported actor disagrees with the training model; export aborted')
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(path.name + '.tmp')
    with _quiet_torchscript():
        torch.jit.save(deployed, str(tmp))
    os.replace(tmp, path)
    sidecar = {'format': SIDECAR_FORMAT, 'format_version': SIDECAR_VERSION, **contract,
               'actor_file': path.name, 'actor_sha256': file_sha256(path),
               'network': {'hidden_dims': actor_critic.actor_hidden_dims, 'activation': actor_critic.activation,
                           'normalizer_inside': actor_critic.normalize_observations,
                           'input': 'raw observation vector in obs_layout order',
                           'output': 'mean action (raw policy output, decoded by the spec module)'},
               'training': _jsonable(training or {})}
    json_path = sidecar_path(path)
    json_path.write_text(json.dumps(sidecar, indent=2) + '\n')
    return path, json_path


def load_actor(path: str | pathlib.Path, expected: dict[str, Any] | None = None) -> LoadedActor:
    """Load an exported actor, refusing it (ActorMismatchError) unless its sidecar matches `expected`.

    `expected` defaults to the running code's spec contract (`current_spec_contract()`).
    """
    path = pathlib.Path(path)
    json_path = sidecar_path(path)
    if not path.is_file():
        raise ActorMismatchError(f'actor file {path} does not exist')
    if not json_path.is_file():
        raise ActorMismatchError(f'actor {path} has no sidecar {json_path.name}: cannot check it fits this spec')
    try:
        metadata = json.loads(json_path.read_text())
    except json.JSONDecodeError as err:
        raise ActorMismatchError(f'sidecar {json_path} is not valid JSON: {err}') from err
    if metadata.get('format') != SIDECAR_FORMAT:
        raise ActorMismatchError(f'{json_path} is not a StylePong actor sidecar')
    if metadata.get('format_version') != SIDECAR_VERSION:
        raise ActorMismatchError(f'{json_path} has sidecar version {metadata.get("format_version")}, '
                                 f'this code reads {SIDECAR_VERSION}')
    if metadata.get('actor_sha256') != file_sha256(path):
        raise ActorMismatchError(f'{path.name} does not match the SHA-256 in {json_path.name}: '
                                 f'the actor file was replaced or damaged')
    expected = _jsonable(current_spec_contract() if expected is None else expected)
    differences = [f'{key}: actor has {metadata.get(key)!r}, this code has {expected[key]!r}'
                   for key in CONTRACT_KEYS if key in expected and metadata.get(key) != expected[key]]
    if differences:
        raise ActorMismatchError(f'actor {path} was trained for a different observation/action spec:\n  '
                                 + '\n  '.join(differences))
    with _quiet_torchscript():
        module = torch.jit.load(str(path), map_location='cpu')
    module.eval()
    with torch.no_grad():
        out = module(torch.zeros(1, int(metadata['num_obs'])))
    if tuple(out.shape) != (1, int(metadata['num_actions'])):
        raise ActorMismatchError(f'actor {path} outputs shape {tuple(out.shape)}, '
                                 f'its sidecar promises (1, {metadata["num_actions"]})')
    return LoadedActor(module=module, metadata=metadata, path=path)
