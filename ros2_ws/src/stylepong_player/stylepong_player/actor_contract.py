"""The contract an exported actor carries and the checks a player makes before it runs one (no torch).

An actor is exported (stylepong_policy.rl.export) as TorchScript `<name>.pt` with a sidecar `<name>.json`, and as ONNX
`<name>.onnx` whose metadata_props hold the same contract: spec version, action rate, joint names,
observation layout and action decoding (stylepong_player.spec). Both files are refused unless that
contract equals the running code's spec, with one line that names every difference, so an actor trained
for another robot, another joint order or another observation is never fed the wrong numbers.

This module needs only the standard library and the spec's constants: the robot computer checks and runs
the ONNX actor without torch. ONNX metadata values are JSON text, one property per key.
"""

from __future__ import annotations

import hashlib
import json
import pathlib
from typing import Any

SIDECAR_FORMAT = 'stylepong-actor'
SIDECAR_VERSION = 1
# All of these must match exactly for an actor to load.
CONTRACT_KEYS = (
    'spec_version',
    'action_rate_hz',
    'joint_names',
    'obs_layout',
    'num_obs',
    'num_actions',
    'action_decoding',
)
ONNX_INPUT = 'observation'
ONNX_OUTPUT = 'action'


class ActorMismatchError(ValueError):
    """The actor file does not fit the running code's observation/action spec (or is damaged)."""


def jsonable(value: Any) -> Any:
    """Tuples to lists and numpy/torch scalars to numbers, so a round trip through JSON compares equal."""
    if isinstance(value, dict):
        return {str(k): jsonable(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [jsonable(v) for v in value]
    if hasattr(value, 'tolist'):
        return jsonable(value.tolist())
    return value


def current_spec_contract() -> dict[str, Any]:
    """The running code's observation/action contract, read from `stylepong_player.spec`."""
    from stylepong_player import spec

    layout = [[str(name), int(size)] for name, size in spec.OBS_LAYOUT]
    return jsonable(
        {
            'spec_version': spec.SPEC_VERSION,
            'action_rate_hz': float(spec.ACTION_RATE_HZ),
            'joint_names': list(spec.JOINT_NAMES),
            'obs_layout': layout,
            'num_obs': spec.NUM_OBS,
            'num_actions': spec.NUM_ACTIONS,
            'action_decoding': spec.action_decoding(),
        }
    )


def contract_differences(metadata: dict[str, Any], expected: dict[str, Any]) -> list[str]:
    """'key: actor has X, this code has Y' for every contract key on which the two disagree."""
    expected = jsonable(expected)
    return [
        f'{key}: actor has {metadata.get(key)!r}, this code has {expected[key]!r}'
        for key in CONTRACT_KEYS
        if key in expected and metadata.get(key) != expected[key]
    ]


def check_contract(
    metadata: dict[str, Any], source: str | pathlib.Path, expected: dict[str, Any] | None = None
) -> None:
    """ActorMismatchError (one line) unless `metadata` is a StylePong actor's and fits `expected`
    (default: the running code's spec)."""
    if metadata.get('format') != SIDECAR_FORMAT:
        raise ActorMismatchError(f'{source} is not a StylePong actor (format {metadata.get("format")!r})')
    if metadata.get('format_version') != SIDECAR_VERSION:
        raise ActorMismatchError(
            f'{source} has format version {metadata.get("format_version")!r}, this code reads {SIDECAR_VERSION}'
        )
    differences = contract_differences(metadata, current_spec_contract() if expected is None else expected)
    if differences:
        raise ActorMismatchError(
            f'actor {source} was trained for a different observation/action spec: ' + '; '.join(differences)
        )


def file_sha256(path: str | pathlib.Path) -> str:
    """SHA-256 of a file's content, as hex."""
    digest = hashlib.sha256()
    with open(path, 'rb') as f:
        for chunk in iter(lambda: f.read(1 << 20), b''):
            digest.update(chunk)
    return digest.hexdigest()


def sidecar_path(actor_path: str | pathlib.Path) -> pathlib.Path:
    """The JSON sidecar beside an exported actor."""
    return pathlib.Path(actor_path).with_suffix('.json')


def onnx_path(actor_path: str | pathlib.Path) -> pathlib.Path:
    """The ONNX file beside an exported actor."""
    return pathlib.Path(actor_path).with_suffix('.onnx')


def read_sidecar(actor_path: str | pathlib.Path, expected: dict[str, Any] | None = None) -> dict[str, Any]:
    """The checked sidecar of a TorchScript actor: it exists, is the file's (SHA-256) and fits the spec."""
    path = pathlib.Path(actor_path)
    json_path = sidecar_path(path)
    if not path.is_file():
        raise ActorMismatchError(f'actor file {path} does not exist')
    if not json_path.is_file():
        raise ActorMismatchError(f'actor {path} has no sidecar {json_path.name}: cannot check it fits this spec')
    try:
        metadata = json.loads(json_path.read_text())
    except json.JSONDecodeError as err:
        raise ActorMismatchError(f'sidecar {json_path} is not valid JSON: {err}') from err
    if not isinstance(metadata, dict):
        raise ActorMismatchError(f'sidecar {json_path} is not a JSON object')
    if metadata.get('format') == SIDECAR_FORMAT and metadata.get('actor_sha256') != file_sha256(path):
        raise ActorMismatchError(
            f'{path.name} does not match the SHA-256 in {json_path.name}: the actor file was replaced or damaged'
        )
    check_contract(metadata, path, expected)
    return metadata


def onnx_metadata_props(metadata: dict[str, Any]) -> dict[str, str]:
    """ONNX metadata_props (string -> string) holding `metadata`: each key's value as JSON text."""
    return {str(key): json.dumps(jsonable(value)) for key, value in metadata.items()}


def parse_onnx_metadata(props: dict[str, str], source: str | pathlib.Path) -> dict[str, Any]:
    """Decode an ONNX model's metadata_props (JSON values); ActorMismatchError if one is not JSON."""
    metadata = {}
    for key, text in props.items():
        try:
            metadata[key] = json.loads(text)
        except json.JSONDecodeError as err:
            raise ActorMismatchError(f'{source}: metadata {key!r} is not JSON ({err})') from err
    return metadata
