"""A small vectorised task with the TableTennisEnv interface, for testing PPO and the runner alone.

Reach-the-target in the plane: the actor sees a noisy position and the target, the critic also sees
the true position and the time left (an asymmetric actor-critic has something to gain). Reaching the
target within 0.1 is a success that ends the episode; otherwise a time limit ends it as a failure.
A random policy succeeds in well under half the episodes; a policy that learnt succeeds in nearly all.
"""
from __future__ import annotations

import torch

FAILURE_REASONS = ('returned', 'timeout')


class ReachTask:
    num_obs = 4
    num_critic_obs = 7
    num_actions = 2

    def __init__(self, num_envs: int = 128, device: str = 'cpu', seed: int = 0, episode_steps: int = 30,
                 obs_noise: float = 0.02):
        self.num_envs = num_envs
        self.device = torch.device(device)
        self.episode_steps = episode_steps
        self.obs_noise = obs_noise
        self.generator = torch.Generator(device=self.device)
        self.generator.manual_seed(seed)
        self.position = torch.zeros(num_envs, 2, device=self.device)
        self.target = torch.zeros(num_envs, 2, device=self.device)
        self.steps = torch.zeros(num_envs, device=self.device)

    def _uniform(self, n: int, low: float, high: float) -> torch.Tensor:
        return low + (high - low) * torch.rand(n, 2, generator=self.generator, device=self.device)

    def _reset_envs(self, idx: torch.Tensor) -> None:
        self.position[idx] = self._uniform(len(idx), -1.0, 1.0)
        self.target[idx] = self._uniform(len(idx), -1.0, 1.0)
        self.steps[idx] = 0.0

    def _observe(self) -> tuple[torch.Tensor, torch.Tensor]:
        noise = self.obs_noise * torch.randn(self.num_envs, 2, generator=self.generator, device=self.device)
        obs = torch.cat([self.position + noise, self.target], dim=-1)
        time_left = (1.0 - self.steps / self.episode_steps)[:, None]
        critic_obs = torch.cat([obs, self.position, time_left], dim=-1)
        return obs, critic_obs

    def reset(self) -> tuple[torch.Tensor, torch.Tensor]:
        self._reset_envs(torch.arange(self.num_envs, device=self.device))
        return self._observe()

    def step(self, actions: torch.Tensor):
        self.position += 0.1 * actions.clamp(-1.0, 1.0)
        self.steps += 1.0
        distance = (self.position - self.target).norm(dim=-1)
        success = distance < 0.1
        time_outs = (self.steps >= self.episode_steps) & ~success
        dones = success | time_outs
        rewards = -0.1 * distance + 2.0 * success.float()
        info = {'time_outs': time_outs, 'ball_done': dones.clone(), 'ball_success': success.clone(),
                'ball_hit': distance < 0.3, 'ball_reason': torch.where(success, 0, 1).to(torch.int64),
                'episode': {'distance': float(distance.mean())}, 'arm_state': torch.zeros(self.num_envs, 12)}
        done_idx = dones.nonzero(as_tuple=False).squeeze(-1)
        if done_idx.numel():
            self._reset_envs(done_idx)
        obs, critic_obs = self._observe()
        return obs, critic_obs, rewards, dones, info
