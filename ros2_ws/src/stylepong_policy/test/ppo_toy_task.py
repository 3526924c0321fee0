"""A small vectorised task with the batched-env contract (stylepong_policy.rl.env), for testing PPO, the
runner and the motion prior alone.

Reach-the-target in the plane: the actor sees a noisy position and the target, the critic also sees
the true position and the time left (an asymmetric actor-critic has something to gain). Reaching the
target within 0.1 is a success that ends the episode; otherwise a time limit ends it as a failure.
A random policy succeeds in well under half the episodes; a policy that learnt succeeds in nearly all.
The style frame is the position and the velocity of the last step.
"""

from __future__ import annotations

import torch

# PPO's settings that learn this task in a few seconds (test_ppo's and test_amp's runs).
TOY_PPO = {
    'num_steps_per_env': 16,
    'num_mini_batches': 2,
    'num_learning_epochs': 4,
    'learning_rate': 3e-3,
    'entropy_coef': 0.005,
}


class ReachTask:
    num_obs = 4
    num_critic_obs = 7
    num_actions = 2
    num_style_features = 4
    step_size = 0.1  # position change per step at full action

    def __init__(
        self, num_envs: int = 128, device: str = 'cpu', seed: int = 0, episode_steps: int = 30, obs_noise: float = 0.02
    ):
        self.num_envs = num_envs
        self.device = torch.device(device)
        self.episode_steps = episode_steps
        self.obs_noise = obs_noise
        self.generator = torch.Generator(device=self.device)
        self.generator.manual_seed(seed)
        self.position = torch.zeros(num_envs, 2, device=self.device)
        self.target = torch.zeros(num_envs, 2, device=self.device)
        self.steps = torch.zeros(num_envs, device=self.device)
        self.velocity = torch.zeros(num_envs, 2, device=self.device)

    def _uniform(self, n: int, low: float, high: float) -> torch.Tensor:
        return low + (high - low) * torch.rand(n, 2, generator=self.generator, device=self.device)

    def _reset_envs(self, idx: torch.Tensor) -> None:
        self.position[idx] = self._uniform(len(idx), -1.0, 1.0)
        self.target[idx] = self._uniform(len(idx), -1.0, 1.0)
        self.steps[idx] = 0.0
        self.velocity[idx] = 0.0

    def _observe(self) -> tuple[torch.Tensor, torch.Tensor]:
        noise = self.obs_noise * torch.randn(self.num_envs, 2, generator=self.generator, device=self.device)
        obs = torch.cat([self.position + noise, self.target], dim=-1)
        time_left = (1.0 - self.steps / self.episode_steps)[:, None]
        critic_obs = torch.cat([obs, self.position, time_left], dim=-1)
        return obs, critic_obs

    def reset(self) -> tuple[torch.Tensor, torch.Tensor]:
        self._reset_envs(torch.arange(self.num_envs, device=self.device))
        return self._observe()

    def style_state(self) -> torch.Tensor:
        return torch.cat((self.position, self.velocity), dim=-1)

    def step(self, actions: torch.Tensor):
        self.velocity = self.step_size * actions.clamp(-1.0, 1.0)
        self.position += self.velocity
        self.steps += 1.0
        distance = (self.position - self.target).norm(dim=-1)
        success = distance < 0.1
        time_outs = (self.steps >= self.episode_steps) & ~success
        dones = success | time_outs
        rewards = -0.1 * distance + 2.0 * success.float()
        done_idx = dones.nonzero(as_tuple=False).squeeze(-1)
        extras = {
            'time_outs': time_outs,
            'style_state': self.style_state(),
            'success': success.clone(),
            'log': {},
            'log_weight': int(done_idx.numel()),
        }
        if done_idx.numel():
            ended = success[done_idx].float().mean().item()
            extras['log'] = {
                'success_rate': ended,
                'timeout_rate': 1.0 - ended,
                'final_distance': float(distance[done_idx].mean()),
            }
            self._reset_envs(done_idx)
        obs, critic_obs = self._observe()
        return obs, critic_obs, rewards, dones, extras
