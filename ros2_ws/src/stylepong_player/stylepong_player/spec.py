"""The observation/action contract between the trained actor and whatever runs it.

The contract in words: docs/DESIGN.md, "Observation and action contract".

The batched training env (stylepong_policy.training.task, torch tensors) and the `player` node (numpy arrays) both
build the actor's observation with `build_observation` and decode its action here and nowhere else: a
train/deploy mismatch fails silently on the robot, so the tests feed both kinds of array the same state
and require identical values. The exporter writes
SPEC_VERSION, ACTION_RATE_HZ, JOINT_NAMES, OBS_LAYOUT and `action_decoding()` into the actor's sidecar
JSON; a player refuses an actor whose contract differs from this module's. Change anything here and
bump SPEC_VERSION.

Observation (one row per environment, float32, in OBS_LAYOUT order, all in the world frame of
world_spec, SI units):
  joint_position_offset_rad  q - HOME_JOINT_POSITIONS_RAD, URDF joint order (JOINT_NAMES)
  joint_velocity_rad_s       qdot
  ball_position_m            ball centre
  ball_velocity_m_s          ball velocity
  goal_xy_m                  centre of the goal region on the opponent's half
  last_action                the previous action as applied (clipped to [-1, 1])
What the robot can sense only: the critic's privileged inputs are the task's business.
Sensing noise and latency are not part of the contract (the real sensors bring their own); the
training env (stylepong_policy.training.task) simulates them before calling `build_observation`.

Action (one row per environment, NUM_ACTIONS = 6, at ACTION_RATE_HZ): joint position targets
  q_cmd = clip(HOME + ACTION_SCALE_RAD * clip(a, -1, 1), URDF lower limit, URDF upper limit)
sent to the joint position servo (ur5_sim's or the real driver's forward_position_controller).
Why absolute targets around home (the paper's choice) and this scale: a stroke's poses lie within about
1.5 rad of home on every joint (inverse kinematics over the hitting region: 90th percentiles 0.7-1.6 rad).
"""

from __future__ import annotations

import functools
from typing import TYPE_CHECKING

import numpy as np

from stylepong_description import robot_cell, robot_model

SPEC_VERSION = 1
ACTION_RATE_HZ = float(robot_cell.POLICY_RATE_HZ)
JOINT_NAMES: tuple[str, ...] = robot_model.JOINT_NAMES
NUM_ACTIONS = len(JOINT_NAMES)
HOME_JOINT_POSITIONS_RAD: tuple[float, ...] = tuple(float(x) for x in robot_cell.HOME_JOINT_POSITIONS_RAD)
ACTION_SCALE_RAD: tuple[float, ...] = (1.5,) * NUM_ACTIONS
ACTION_CLIP = 1.0

OBS_LAYOUT: tuple[tuple[str, int], ...] = (
    ('joint_position_offset_rad', NUM_ACTIONS),
    ('joint_velocity_rad_s', NUM_ACTIONS),
    ('ball_position_m', 3),
    ('ball_velocity_m_s', 3),
    ('goal_xy_m', 2),
    ('last_action', NUM_ACTIONS),
)
NUM_OBS = sum(size for _, size in OBS_LAYOUT)


def observation_slice(name: str) -> slice:
    """The columns of OBS_LAYOUT's entry `name` in an observation row (KeyError for an unknown name)."""
    start = 0
    for entry, size in OBS_LAYOUT:
        if entry == name:
            return slice(start, start + size)
        start += size
    raise KeyError(f'no {name!r} in OBS_LAYOUT: {[entry for entry, _ in OBS_LAYOUT]}')


# torch is imported inside the functions that use it: the constants above are the whole contract, and the
# player's ONNX path reads them and builds its observation with numpy on a robot computer that has no torch.
if TYPE_CHECKING:
    import torch


def action_decoding() -> dict:
    """The action's meaning, for the exported actor's sidecar JSON."""
    limits = robot_model.joint_limits()
    return {
        'kind': 'joint_position_targets',
        'home_rad': list(HOME_JOINT_POSITIONS_RAD),
        'scale_rad': list(ACTION_SCALE_RAD),
        'clip': ACTION_CLIP,
        'lower_limit_rad': [float(x) for x in limits.lower_rad],
        'upper_limit_rad': [float(x) for x in limits.upper_rad],
    }


@functools.lru_cache(maxsize=None)
def _rows_on(device: torch.device) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor, torch.Tensor]:
    """(home, scale, lower limit, upper limit) as float32 rows on `device`, made once per device: made
    per call they were a host-to-device copy, a wait on a GPU, at every training step."""
    import torch

    limits = robot_model.joint_limits()
    return tuple(
        torch.as_tensor(values, dtype=torch.float32, device=device)
        for values in (HOME_JOINT_POSITIONS_RAD, ACTION_SCALE_RAD, limits.lower_rad, limits.upper_rad)
    )


@functools.lru_cache(maxsize=1)
def _numpy_rows() -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(home, scale, lower limit, upper limit) as float32 numpy rows: the player's side of `_rows_on`."""
    limits = robot_model.joint_limits()
    return tuple(
        np.asarray(values, dtype=np.float32)
        for values in (HOME_JOINT_POSITIONS_RAD, ACTION_SCALE_RAD, limits.lower_rad, limits.upper_rad)
    )


def clip_action(action):
    """The policy's raw output [N, 6] limited to the action range (what is applied and observed back), as a
    torch tensor for a tensor (training) and a numpy array for an array (the player)."""
    if isinstance(action, np.ndarray):
        return np.clip(action, -ACTION_CLIP, ACTION_CLIP)
    return action.clamp(-ACTION_CLIP, ACTION_CLIP)


def decode_action(action):
    """Joint position targets [N, 6] (rad, URDF order) for raw actions [N, 6] (or one action [6]), computed
    in float32 for a torch tensor (training) and a numpy array (the player) alike, with the same operations
    in the same order so that both give identical values."""
    if isinstance(action, np.ndarray):
        home, scale, lower, upper = _numpy_rows()
        target = home + scale * clip_action(action.astype(np.float32))
        return np.maximum(np.minimum(target, upper), lower)
    import torch

    home, scale, lower, upper = _rows_on(action.device)
    target = home + scale * clip_action(action.to(torch.float32))
    return torch.maximum(torch.minimum(target, upper), lower)


def build_observation(
    joint_positions_rad, joint_velocities_rad_s, ball_position_m, ball_velocity_m_s, goal_xy_m, last_action
):
    """The actor's observation [N, NUM_OBS] float32 from the sensed state (rows = environments), as torch
    tensors when the joint positions are one (training), else as a numpy array (the player).

    joint_* [N, 6] in URDF order, ball_* [N, 3], goal_xy_m [N, 2], last_action [N, 6] (clipped).
    """
    parts = (joint_positions_rad, joint_velocities_rad_s, ball_position_m, ball_velocity_m_s, goal_xy_m, last_action)
    for (name, size), part in zip(OBS_LAYOUT, parts):
        if part.shape[-1] != size:
            raise ValueError(f'{name} needs {size} values per row, got shape {tuple(part.shape)}')
    if isinstance(joint_positions_rad, np.ndarray):
        rows = [np.asarray(p, dtype=np.float32) for p in parts]
        rows[0] = rows[0] - np.asarray(HOME_JOINT_POSITIONS_RAD, dtype=np.float32)
        return np.concatenate(rows, axis=-1)
    import torch

    home = _rows_on(joint_positions_rad.device)[0]
    rows = [p.to(torch.float32) for p in parts]
    rows[0] = rows[0] - home
    return torch.cat(rows, dim=-1)
