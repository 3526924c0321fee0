"""The observation/action contract: the player's path and the training env's path give identical tensors."""

import json
import random

import numpy as np
import pytest
import torch

from stylepong_description import robot_model
from stylepong_player import player_core, spec
from stylepong_policy.training import task


def test_layout_and_contract():
    assert spec.NUM_OBS == sum(size for _, size in spec.OBS_LAYOUT) == 26
    assert spec.JOINT_NAMES == robot_model.JOINT_NAMES and spec.NUM_ACTIONS == 6
    assert spec.ACTION_RATE_HZ == 60.0
    decoding = json.loads(json.dumps(spec.action_decoding()))
    assert decoding['home_rad'] == list(spec.HOME_JOINT_POSITIONS_RAD)


def test_observation_slices_tile_the_layout_in_order():
    slices = [spec.observation_slice(name) for name, _ in spec.OBS_LAYOUT]
    assert [s.stop - s.start for s in slices] == [size for _, size in spec.OBS_LAYOUT]
    assert slices[0].start == 0 and slices[-1].stop == spec.NUM_OBS
    assert all(a.stop == b.start for a, b in zip(slices, slices[1:]))
    with pytest.raises(KeyError):
        spec.observation_slice('paddle_position_m')


def test_decode_action_is_home_plus_scaled_clipped_action_within_limits():
    limits = robot_model.joint_limits()
    zero = spec.decode_action(torch.zeros(1, 6))
    assert torch.equal(zero[0], torch.tensor(spec.HOME_JOINT_POSITIONS_RAD, dtype=torch.float32))
    big = spec.decode_action(torch.full((1, 6), 50.0))
    assert torch.equal(big, spec.decode_action(torch.ones(1, 6)))  # clipped to the action range
    expected = torch.tensor(spec.HOME_JOINT_POSITIONS_RAD) + torch.tensor(spec.ACTION_SCALE_RAD)
    expected = torch.minimum(expected, torch.tensor(limits.upper_rad, dtype=torch.float32))
    torch.testing.assert_close(big[0], expected.to(torch.float32))


def _player_inputs(env, i, order):
    """What the player node would read from /joint_states (in `order`, plus a gripper joint) and /ball/state."""
    q = env.world.q_rad[:, i].tolist()
    qd = env.world.qd_rad_s[:, i].tolist()
    names = [spec.JOINT_NAMES[k] for k in order] + ['gripper_joint']
    positions = [q[k] for k in order] + [0.3]
    velocities = [qd[k] for k in order] + [0.0]
    return (
        names,
        positions,
        velocities,
        env.world.ball_pos_m[:, i].tolist(),
        env.world.ball_vel_m_s[:, i].tolist(),
        env.goal_xy_m[i].tolist(),
        env.last_action[i].tolist(),
    )


def _player_observation(names, positions, velocities, ball_position_m, ball_velocity_m_s, goal_xy_m, last_action):
    """What the player builds from those messages: its joint order, then its observation."""
    index = player_core.JointOrder().index(names)
    assert index is not None, names
    return player_core.build_observation(
        np.asarray(positions)[index],
        np.asarray(velocities)[index],
        np.asarray(ball_position_m),
        np.asarray(ball_velocity_m_s),
        np.asarray(goal_xy_m),
        np.asarray(last_action),
    )


def test_player_path_and_env_path_give_identical_observations():
    """Noise and latency off (the protocol's nominal env): the same state through both paths."""
    env = task.make_env(task.TaskConfig(num_envs=8, randomize=False), 'cpu', seed=5)
    obs, _ = env.reset()
    generator = torch.Generator().manual_seed(0)
    rng = random.Random(0)
    for step in range(40):
        for i in range(env.num_envs):
            order = list(range(6))
            rng.shuffle(order)
            player = torch.from_numpy(_player_observation(*_player_inputs(env, i, order)))
            assert player.dtype == obs.dtype and player.shape == (1, env.num_obs)
            assert torch.equal(player[0], obs[i]), (step, i, player[0] - obs[i])
        obs, _, _, _, _ = env.step(torch.randn(env.num_envs, 6, generator=generator))


def test_env_sends_the_decoded_action_to_the_servo():
    env = task.make_env(task.TaskConfig(num_envs=4, randomize=False), 'cpu', seed=1)
    env.reset()
    action = torch.tensor([[0.3, -0.2, 0.5, 2.0, -1.5, 0.0]] * 4)
    env.step(action)
    assert torch.equal(env.world.q_cmd_rad.T, spec.decode_action(action).to(env.world.q_cmd_rad.dtype))
    assert torch.equal(env.last_action, spec.clip_action(action))


def test_player_path_rejects_bad_input():
    names, zeros = list(spec.JOINT_NAMES), np.zeros(6)
    assert player_core.JointOrder().index(names[:5]) is None  # an arm joint missing
    with pytest.raises(ValueError, match='goal_xy_m'):
        player_core.build_observation(zeros, zeros, np.zeros(3), np.zeros(3), np.zeros(3), zeros)
    with pytest.raises(ValueError, match='joint_velocity_rad_s'):
        player_core.build_observation(zeros, zeros[:4], np.zeros(3), np.zeros(3), np.zeros(2), zeros)
    with pytest.raises(ValueError, match='ball_position_m'):
        spec.build_observation(
            torch.zeros(2, 6),
            torch.zeros(2, 6),
            torch.zeros(2, 2),
            torch.zeros(2, 3),
            torch.zeros(2, 2),
            torch.zeros(2, 6),
        )
