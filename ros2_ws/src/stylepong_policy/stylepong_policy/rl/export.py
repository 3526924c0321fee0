"""Export the actor for deployment: TorchScript and ONNX with the observation normaliser inside, plus a sidecar.

Both files map the raw observation vector of the spec module to the mean action (the raw policy output
the spec module decodes into joint position targets):
  <name>.pt    TorchScript (torch or libtorch players, `evaluate`), checked against
  <name>.json  its sidecar: the contract (spec version, rates, joint names, observation layout, action
               decoding), the file's SHA-256, the network and training facts;
  <name>.onnx  the same function for onnxruntime (the `player` default: no torch on the robot computer),
               the sidecar's contract in its metadata_props (stylepong_player.actor_contract).
A player refuses an actor built for a different observation/action contract instead of silently feeding
it the wrong numbers.

The ONNX file of an already exported actor (e.g. the shipped one) is written with
    python3 -m stylepong_policy.rl.export --onnx ros2_ws/src/stylepong_policy/models/ppo_actor.pt
"""

from __future__ import annotations

import argparse
import contextlib
import copy
import json
import os
import pathlib
import sys
import warnings
from dataclasses import dataclass
from typing import Any

import torch
from torch import nn

from stylepong_player.actor_contract import (  # noqa: F401  (re-exported: the names callers import from here)
    CONTRACT_KEYS,
    ONNX_INPUT,
    ONNX_OUTPUT,
    SIDECAR_FORMAT,
    SIDECAR_VERSION,
    ActorMismatchError,
    current_spec_contract,
    file_sha256,
    jsonable,
    onnx_metadata_props,
    onnx_path,
    read_sidecar,
    sidecar_path,
)

from .networks import ActorCritic

# The ONNX opset: what onnxruntime 1.32 runs natively, and Gemm/Elu/Clip as the MLP needs them.
ONNX_OPSET = 17
# ONNX and TorchScript must agree this closely on the export's probe (float32 rounding of one MLP).
ONNX_TOLERANCE = 1e-5


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
    """torch 2.13 flags torch.jit (and the TorchScript-based ONNX exporter) as deprecated in favour of
    torch.export; TorchScript is still what a Python or libtorch player loads in one call, and the
    TorchScript exporter is the one that takes a frozen ScriptModule without onnxscript, so only those
    warnings are silenced, only here."""
    with warnings.catch_warnings():
        warnings.filterwarnings('ignore', message=r'`torch\.jit\.', category=DeprecationWarning)
        warnings.filterwarnings(
            'ignore', message=r'.*legacy TorchScript-based ONNX export', category=DeprecationWarning
        )
        warnings.filterwarnings('ignore', message=r'The feature will be removed', category=DeprecationWarning)
        warnings.filterwarnings('ignore', message=r'no signature found for', category=UserWarning)
        yield


@dataclass
class LoadedActor:
    """An exported TorchScript actor with its contract metadata; call it on observations."""

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


def build_deployed_actor(actor_critic: ActorCritic) -> torch.jit.ScriptModule:
    """Script + freeze a CPU copy of the actor and its normaliser (the training model is left untouched)."""
    normalizer = copy.deepcopy(actor_critic.obs_normalizer) if actor_critic.normalize_observations else nn.Identity()
    module = DeployedActor(normalizer, copy.deepcopy(actor_critic.actor)).cpu().eval()
    # Freezing folds weights and normaliser statistics into constants: the file is self-contained.
    with _quiet_torchscript():
        return torch.jit.freeze(torch.jit.script(module))


def _onnx_metadata(sidecar: dict[str, Any]) -> dict[str, Any]:
    """What the ONNX file carries: the sidecar less what describes the .pt file itself."""
    metadata = {k: v for k, v in sidecar.items() if k not in ('actor_file', 'actor_sha256')}
    metadata['exported_from'] = {'file': sidecar.get('actor_file'), 'sha256': sidecar.get('actor_sha256')}
    return metadata


def export_onnx(module: torch.jit.ScriptModule, path: str | pathlib.Path, metadata: dict[str, Any]) -> pathlib.Path:
    """Write `module` as ONNX at `path` (batch dimension dynamic) with `metadata` in its metadata_props,
    after checking that onnxruntime computes what the module computes. Returns the path."""
    import onnx
    import onnxruntime

    path = pathlib.Path(path)
    num_obs = int(metadata['num_obs'])
    tmp = path.with_name(path.name + '.tmp')
    probe = torch.randn(16, num_obs) * 3.0
    with _quiet_torchscript(), torch.no_grad():
        expected = module(probe).numpy()
        torch.onnx.export(
            module,
            (probe[:1],),
            str(tmp),
            dynamo=False,
            opset_version=ONNX_OPSET,
            input_names=[ONNX_INPUT],
            output_names=[ONNX_OUTPUT],
            dynamic_axes={ONNX_INPUT: {0: 'batch'}, ONNX_OUTPUT: {0: 'batch'}},
        )
    model = onnx.load(str(tmp))
    del model.metadata_props[:]
    for key, value in onnx_metadata_props(metadata).items():
        model.metadata_props.add(key=key, value=value)
    model.doc_string = 'StylePong actor: raw observation [batch, num_obs] -> mean action [batch, num_actions]'
    onnx.checker.check_model(model)
    onnx.save(model, str(tmp))
    session = onnxruntime.InferenceSession(str(tmp), providers=['CPUExecutionProvider'])
    got = session.run([ONNX_OUTPUT], {ONNX_INPUT: probe.numpy()})[0]
    error = float(abs(got - expected).max())
    if error > ONNX_TOLERANCE:
        tmp.unlink()
        raise RuntimeError(f'the ONNX actor differs from TorchScript by {error:.2e}; export aborted')
    os.replace(tmp, path)
    return path


def export_actor(
    actor_critic: ActorCritic,
    path: str | pathlib.Path,
    contract: dict[str, Any],
    training: dict[str, Any] | None = None,
    onnx: bool = True,
) -> tuple[pathlib.Path, pathlib.Path]:
    """Write the TorchScript actor at `path`, its sidecar JSON beside it and (onnx) `<name>.onnx`;
    returns (actor path, sidecar path)."""
    path = pathlib.Path(path)
    contract = jsonable(contract)
    missing = [k for k in CONTRACT_KEYS if k not in contract]
    if missing:
        raise ValueError(f'contract lacks {missing}')
    if (contract['num_obs'], contract['num_actions']) != (actor_critic.num_obs, actor_critic.num_actions):
        raise ActorMismatchError(
            f'the network has {actor_critic.num_obs} inputs and {actor_critic.num_actions} outputs, the spec says '
            f'{contract["num_obs"]} and {contract["num_actions"]}'
        )
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
    sidecar = {
        'format': SIDECAR_FORMAT,
        'format_version': SIDECAR_VERSION,
        **contract,
        'actor_file': path.name,
        'actor_sha256': file_sha256(path),
        'network': {
            'hidden_dims': actor_critic.actor_hidden_dims,
            'activation': actor_critic.activation,
            'normalizer_inside': actor_critic.normalize_observations,
            'input': 'raw observation vector in obs_layout order',
            'output': 'mean action (raw policy output, decoded by the spec module)',
        },
        'training': jsonable(training or {}),
    }
    json_path = sidecar_path(path)
    json_path.write_text(json.dumps(sidecar, indent=2) + '\n')
    if onnx:
        export_onnx(deployed, onnx_path(path), _onnx_metadata(sidecar))
    return path, json_path


def load_actor(path: str | pathlib.Path, expected: dict[str, Any] | None = None) -> LoadedActor:
    """Load an exported TorchScript actor, refusing it (ActorMismatchError) unless its sidecar matches
    `expected` (default: the running code's spec contract, `current_spec_contract()`)."""
    path = pathlib.Path(path)
    metadata = read_sidecar(path, expected)
    with _quiet_torchscript():
        module = torch.jit.load(str(path), map_location='cpu')
    module.eval()
    with torch.no_grad():
        out = module(torch.zeros(1, int(metadata['num_obs'])))
    if tuple(out.shape) != (1, int(metadata['num_actions'])):
        raise ActorMismatchError(
            f'actor {path} outputs shape {tuple(out.shape)}, its sidecar promises (1, {metadata["num_actions"]})'
        )
    return LoadedActor(module=module, metadata=metadata, path=path)


def write_onnx_for(actor_path: str | pathlib.Path, path: str | pathlib.Path | None = None) -> pathlib.Path:
    """`<name>.onnx` for an exported `<name>.pt` (checked against its sidecar and this code's spec), beside
    it or at `path`."""
    actor = load_actor(actor_path)
    return write_onnx_of(actor, onnx_path(actor.path) if path is None else path)


def write_onnx_of(actor: LoadedActor, path: str | pathlib.Path) -> pathlib.Path:
    """`path`, the ONNX file of an actor already loaded (load_actor), its sidecar's contract inside."""
    return export_onnx(actor.module, path, _onnx_metadata(actor.metadata))


def main(argv: list[str] | None = None) -> int:
    """Write the ONNX file beside each exported actor given."""
    parser = argparse.ArgumentParser(
        prog='python3 -m stylepong_policy.rl.export', description='Write the ONNX file of exported TorchScript actors.'
    )
    parser.add_argument(
        '--onnx',
        nargs='+',
        type=pathlib.Path,
        required=True,
        metavar='ACTOR.pt',
        help='exported actors (with their sidecar .json); writes <name>.onnx beside each',
    )
    args = parser.parse_args(argv)
    for actor_path in args.onnx:
        try:
            written = write_onnx_for(actor_path)
        except ActorMismatchError as err:
            print(f'export: {err}', file=sys.stderr)
            return 2
        print(f'wrote {written} ({written.stat().st_size} bytes), contract in its metadata_props')
    return 0


if __name__ == '__main__':
    sys.exit(main())
