"""Proximal policy optimisation (Schulman et al. 2017) with clipped surrogate and value losses.

Follows rsl_rl's PPO: Gaussian policy with learnable std, entropy bonus, gradient-norm clipping, and
a learning rate adapted per minibatch from the KL between the rollout policy and the current one.
"""

from __future__ import annotations

from dataclasses import dataclass

import torch
from torch import nn

from .config import PPOConfig
from .networks import ActorCritic
from .storage import RolloutStorage


@dataclass
class PolicyStep:
    """What one policy query during a rollout produces (all detached)."""

    actions: torch.Tensor
    log_probs: torch.Tensor
    values: torch.Tensor
    mean: torch.Tensor
    std: torch.Tensor
    norm_obs: torch.Tensor
    norm_critic_obs: torch.Tensor


def gaussian_kl(
    mean_old: torch.Tensor, std_old: torch.Tensor, mean_new: torch.Tensor, std_new: torch.Tensor
) -> torch.Tensor:
    """KL(N_old || N_new) of diagonal Gaussians, summed over action dimensions: shape [B]."""
    return (
        torch.log(std_new / std_old)
        + (std_old.square() + (mean_old - mean_new).square()) / (2.0 * std_new.square())
        - 0.5
    ).sum(-1)


def make_adam(params, lr: float) -> torch.optim.Adam:
    """Adam with the fused kernel where this torch build has one (fewer passes over the parameters)."""
    params = list(params)
    try:
        return torch.optim.Adam(params, lr=lr, fused=True)
    except (RuntimeError, TypeError, ValueError):
        return torch.optim.Adam(params, lr=lr)


class PPO:
    """Proximal policy optimisation of an actor-critic: acting in rollouts and the clipped update."""

    def __init__(self, actor_critic: ActorCritic, cfg: PPOConfig):
        self.actor_critic = actor_critic
        self.cfg = cfg
        self.learning_rate = float(cfg.learning_rate)
        self.optimizer = make_adam(actor_critic.parameters(), self.learning_rate)

    def act(self, obs: torch.Tensor, critic_obs: torch.Tensor) -> PolicyStep:
        """Sample actions for a rollout step, folding its observations into the normalisers first.
        Call under torch.inference_mode()."""
        ac = self.actor_critic
        norm_obs, norm_critic_obs = ac.normalize(obs, critic_obs, update=True)
        dist = ac.distribution(norm_obs)
        actions = dist.sample()
        return PolicyStep(
            actions=actions,
            log_probs=dist.log_prob(actions).sum(-1),
            values=ac.value(norm_critic_obs),
            mean=dist.mean,
            std=dist.stddev,
            norm_obs=norm_obs,
            norm_critic_obs=norm_critic_obs,
        )

    def value(self, critic_obs: torch.Tensor) -> torch.Tensor:
        """V of raw critic observations without touching the normaliser statistics."""
        ac = self.actor_critic
        norm = ac.critic_obs_normalizer(critic_obs) if ac.normalize_observations else critic_obs
        return ac.value(norm)

    def _set_learning_rate(self, lr: float) -> None:
        self.learning_rate = float(min(max(lr, self.cfg.min_learning_rate), self.cfg.max_learning_rate))
        for group in self.optimizer.param_groups:
            group['lr'] = self.learning_rate

    def apply_schedule(self, iteration: int, total_iterations: int) -> None:
        """Per-iteration learning-rate schedules (the adaptive one acts per minibatch in update())."""
        if self.cfg.schedule == 'linear' and total_iterations > 0:
            frac = min(iteration / total_iterations, 1.0)
            self._set_learning_rate(
                self.cfg.learning_rate + frac * (self.cfg.min_learning_rate - self.cfg.learning_rate)
            )
        elif self.cfg.schedule == 'fixed':
            self._set_learning_rate(self.cfg.learning_rate)

    def update(
        self, storage: RolloutStorage, generator: torch.Generator | None = None, update_actor: bool = True
    ) -> dict[str, float]:
        """Several epochs of minibatch gradient steps on a filled storage; returns mean losses and diagnostics.
        update_actor False steps the critic alone (the policy and the learning rate stay as they are)."""
        cfg, ac = self.cfg, self.actor_critic
        totals = {'value_loss': 0.0, 'surrogate_loss': 0.0, 'entropy': 0.0, 'kl': 0.0, 'clip_fraction': 0.0}
        count = 0
        for mb in storage.minibatches(cfg.num_mini_batches, cfg.num_learning_epochs, generator):
            dist = ac.distribution(mb.obs)
            log_probs = dist.log_prob(mb.actions).sum(-1)
            entropy = dist.entropy().sum(-1).mean()
            values = ac.value(mb.critic_obs)

            with torch.no_grad():
                kl = gaussian_kl(mb.old_mean, mb.old_std, dist.mean, dist.stddev).mean()
            if cfg.schedule == 'adaptive' and update_actor:
                # rsl_rl's rule: shrink the step when the policy moved too far, grow it when it barely moved.
                if kl > 2.0 * cfg.desired_kl:
                    self._set_learning_rate(self.learning_rate / 1.5)
                elif 0.0 < kl < 0.5 * cfg.desired_kl:
                    self._set_learning_rate(self.learning_rate * 1.5)

            ratio = torch.exp(log_probs - mb.old_log_probs)
            clipped_ratio = ratio.clamp(1.0 - cfg.clip_param, 1.0 + cfg.clip_param)
            surrogate_loss = -torch.min(ratio * mb.advantages, clipped_ratio * mb.advantages).mean()

            if cfg.use_clipped_value_loss:
                values_clipped = mb.old_values + (values - mb.old_values).clamp(-cfg.clip_param, cfg.clip_param)
                value_error = torch.max((values - mb.returns).square(), (values_clipped - mb.returns).square())
            else:
                value_error = (values - mb.returns).square()
            # Several value streams: each sample's error summed over them, as their values sum to the return.
            value_loss = (value_error if value_error.dim() == 1 else value_error.sum(-1)).mean()

            loss = cfg.value_loss_coef * value_loss
            if update_actor:
                loss = loss + surrogate_loss - cfg.entropy_coef * entropy
            self.optimizer.zero_grad(set_to_none=True)
            loss.backward()
            nn.utils.clip_grad_norm_(ac.parameters(), cfg.max_grad_norm)
            self.optimizer.step()

            totals['value_loss'] += value_loss.item()
            totals['surrogate_loss'] += surrogate_loss.item()
            totals['entropy'] += entropy.item()
            totals['kl'] += kl.item()
            totals['clip_fraction'] += ((ratio - 1.0).abs() > cfg.clip_param).float().mean().item()
            count += 1
        stats = {k: v / max(count, 1) for k, v in totals.items()}
        stats['learning_rate'] = self.learning_rate
        stats['action_std'] = ac.action_std().mean().item()
        return stats
