"""Rollout storage for on-policy learning: T steps x N environments, GAE returns, shuffled minibatches.

With K value streams (rl.networks.ActorCritic's value_streams > 1) rewards, dones, values and returns
hold one column per stream: each stream's advantage is estimated on its own, with its own episode ends
(a stream may end where the episode goes on, so that what it earns later does not flow back to earlier
steps), and the policy follows their sum.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Iterator

import torch

from .env import StepSizes


@dataclass
class Minibatch:
    """One minibatch of rollout samples for a PPO update."""

    obs: torch.Tensor  # normalised actor observations [B, num_obs]
    critic_obs: torch.Tensor  # normalised critic observations [B, num_critic_obs]
    actions: torch.Tensor  # [B, num_actions]
    old_log_probs: torch.Tensor  # [B]
    old_values: torch.Tensor  # [B] (one value stream) or [B, K]
    returns: torch.Tensor  # [B] or [B, K], as old_values
    advantages: torch.Tensor  # [B]
    old_mean: torch.Tensor  # [B, num_actions] (for the KL of the adaptive learning rate)
    old_std: torch.Tensor  # [B, num_actions]


class RolloutStorage:
    """Fixed-size buffers filled step by step during a rollout, then consumed by the PPO update."""

    def __init__(
        self, num_steps: int, num_envs: int, sizes: StepSizes, device: torch.device | str, value_streams: int = 1
    ):
        """num_steps x num_envs steps, each an actor and a critic observation and an action of `sizes`."""
        if value_streams < 1:
            raise ValueError(f'value_streams must be at least 1, got {value_streams}')
        self.num_steps, self.num_envs = int(num_steps), int(num_envs)
        self.device = torch.device(device)
        self.value_streams = int(value_streams)
        stream = () if self.value_streams == 1 else (self.value_streams,)

        def buffer(*shape, dtype=torch.float32):
            return torch.zeros(self.num_steps, self.num_envs, *shape, dtype=dtype, device=self.device)

        self.obs = buffer(sizes.num_obs)
        self.critic_obs = buffer(sizes.num_critic_obs)
        self.actions = buffer(sizes.num_actions)
        self.rewards = buffer(*stream)
        self.dones = buffer(*stream)
        self.values = buffer(*stream)
        self.log_probs = buffer()
        self.mean = buffer(sizes.num_actions)
        self.std = buffer(sizes.num_actions)
        self.returns = buffer(*stream)
        self.advantages = buffer()  # summed over the streams
        self.step = 0

    def add(self, obs, critic_obs, actions, rewards, dones, values, log_probs, mean, std) -> None:
        """Record one environment step (rewards already include any time-out bootstrap). With several value
        streams rewards and values are [N, K] and dones [N] (every stream ends with the episode) or [N, K]."""
        if self.step >= self.num_steps:
            raise RuntimeError('rollout storage is full; call clear() before the next rollout')
        t = self.step
        self.obs[t].copy_(obs)
        self.critic_obs[t].copy_(critic_obs)
        self.actions[t].copy_(actions)
        self.rewards[t].copy_(rewards)
        self.dones[t].copy_(dones if dones.shape == self.dones[t].shape else dones[:, None].expand_as(self.dones[t]))
        self.values[t].copy_(values)
        self.log_probs[t].copy_(log_probs)
        self.mean[t].copy_(mean)
        self.std[t].copy_(std)
        self.step += 1

    def clear(self) -> None:
        self.step = 0

    def compute_returns(
        self, last_values: torch.Tensor, gamma: float, lam: float, normalize_advantages: bool = True
    ) -> None:
        """Generalised advantage estimation (Schulman et al. 2016).

        delta_t = r_t + gamma (1 - d_t) V_{t+1} - V_t,  A_t = delta_t + gamma lam (1 - d_t) A_{t+1},
        returns R_t = A_t + V_t. d_t marks the last step of an episode (its successor belongs to a
        new episode), so nothing flows across episode boundaries. Per stream with several; the policy's
        advantage is their sum.
        """
        if self.step != self.num_steps:
            raise RuntimeError(f'rollout incomplete: {self.step} of {self.num_steps} steps recorded')
        advantage = torch.zeros_like(last_values)
        next_values = last_values
        for t in reversed(range(self.num_steps)):
            not_done = 1.0 - self.dones[t]
            delta = self.rewards[t] + gamma * not_done * next_values - self.values[t]
            advantage = delta + gamma * lam * not_done * advantage
            self.returns[t] = advantage + self.values[t]
            self.advantages[t] = advantage if self.value_streams == 1 else advantage.sum(-1)
            next_values = self.values[t]
        if normalize_advantages:
            self.advantages.copy_((self.advantages - self.advantages.mean()) / (self.advantages.std() + 1e-8))

    def minibatches(
        self, num_minibatches: int, num_epochs: int, generator: torch.Generator | None = None
    ) -> Iterator[Minibatch]:
        """num_epochs passes over the rollout, each split into num_minibatches shuffled minibatches."""
        batch_size = self.num_steps * self.num_envs
        if not 1 <= num_minibatches <= batch_size:
            raise ValueError(f'num_minibatches must be in [1, {batch_size}], got {num_minibatches}')
        flat = {
            name: getattr(self, name).flatten(0, 1)
            for name in ('obs', 'critic_obs', 'actions', 'log_probs', 'values', 'returns', 'advantages', 'mean', 'std')
        }
        size = batch_size // num_minibatches
        for _ in range(num_epochs):
            order = torch.randperm(batch_size, generator=generator, device='cpu').to(self.device)
            for start in range(0, size * num_minibatches, size):
                idx = order[start : start + size]
                yield Minibatch(
                    obs=flat['obs'][idx],
                    critic_obs=flat['critic_obs'][idx],
                    actions=flat['actions'][idx],
                    old_log_probs=flat['log_probs'][idx],
                    old_values=flat['values'][idx],
                    returns=flat['returns'][idx],
                    advantages=flat['advantages'][idx],
                    old_mean=flat['mean'][idx],
                    old_std=flat['std'][idx],
                )
