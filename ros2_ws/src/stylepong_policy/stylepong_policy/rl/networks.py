"""Actor and critic networks: MLPs with a Gaussian policy head whose std is a learnable parameter.

Asymmetric actor-critic: the actor sees only what the robot can sense (the spec module's observation),
the critic also sees privileged simulator state (true ball state, physics parameters, delays). Each has
its own running observation normaliser, kept inside the module so checkpoints and exports carry it.
The critic may estimate several value streams, one per part of the reward (rl.storage says how they are
used); `fit_value_streams` carries a critic over from a network with another number of them.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Sequence

import torch
from torch import nn
from torch.distributions import Normal

from .env import StepSizes
from .normalizer import RunningNormalizer

if TYPE_CHECKING:
    from .config import PolicyConfig

# The settings of rl.config.PolicyConfig that are ActorCritic's own (keep_skill_std is the runner's).
NETWORK_SETTINGS = (
    'actor_hidden_dims',
    'critic_hidden_dims',
    'activation',
    'init_noise_std',
    'min_std',
    'normalize_observations',
)
ACTIVATIONS = {'elu': nn.ELU, 'relu': nn.ReLU, 'tanh': nn.Tanh, 'selu': nn.SELU, 'leaky_relu': nn.LeakyReLU}


def make_mlp(
    in_size: int, hidden_sizes: Sequence[int], out_size: int, activation: str = 'elu', output_gain: float = 1.0
) -> nn.Sequential:
    """Linear -> activation for each hidden size, then a linear output layer.

    Orthogonal initialisation (sqrt(2) gain on hidden layers) as in CleanRL; a small gain on the output
    layer of the actor makes the initial policy's mean actions near zero, i.e. near the default pose.
    """
    if activation not in ACTIVATIONS:
        raise ValueError(f'unknown activation {activation!r}; choose one of {sorted(ACTIVATIONS)}')
    layers: list[nn.Module] = []
    size = in_size
    for hidden in hidden_sizes:
        linear = nn.Linear(size, int(hidden))
        nn.init.orthogonal_(linear.weight, gain=2.0**0.5)
        nn.init.zeros_(linear.bias)
        layers += [linear, ACTIVATIONS[activation]()]
        size = int(hidden)
    head = nn.Linear(size, out_size)
    nn.init.orthogonal_(head.weight, gain=output_gain)
    nn.init.zeros_(head.bias)
    layers.append(head)
    return nn.Sequential(*layers)


class ActorCritic(nn.Module):
    """Gaussian policy pi(a|o) = N(actor(norm(o)), diag(std^2)) and value V(norm_c(o_critic))."""

    def __init__(
        self,
        num_obs: int,
        num_critic_obs: int,
        num_actions: int,
        actor_hidden_dims: Sequence[int],
        critic_hidden_dims: Sequence[int],  # rl.config.PolicyConfig
        activation: str = 'elu',
        init_noise_std: float = 1.0,
        min_std: float = 1e-3,
        normalize_observations: bool = True,
        value_streams: int = 1,
    ):
        super().__init__()
        if init_noise_std <= 0.0:
            raise ValueError(f'init_noise_std must be positive, got {init_noise_std}')
        if value_streams < 1:
            raise ValueError(f'value_streams must be at least 1, got {value_streams}')
        self.value_streams = int(value_streams)
        self.num_obs, self.num_critic_obs, self.num_actions = int(num_obs), int(num_critic_obs), int(num_actions)
        self.actor_hidden_dims = [int(h) for h in actor_hidden_dims]
        self.critic_hidden_dims = [int(h) for h in critic_hidden_dims]
        self.activation = activation
        self.min_std = float(min_std)
        self.actor = make_mlp(num_obs, self.actor_hidden_dims, num_actions, activation, output_gain=0.01)
        self.critic = make_mlp(num_critic_obs, self.critic_hidden_dims, self.value_streams, activation, output_gain=1.0)
        # std itself (not log std) is the parameter, as in rsl_rl; clamped below at min_std when used.
        self.std = nn.Parameter(torch.full((num_actions,), float(init_noise_std)))
        # An optional ceiling on the std (runner: a skill's own, `policy.keep_skill_std`); not a parameter.
        self.max_std: torch.Tensor | None = None
        self.normalize_observations = bool(normalize_observations)
        self.obs_normalizer = RunningNormalizer(num_obs)
        self.critic_obs_normalizer = RunningNormalizer(num_critic_obs)

    @classmethod
    def from_config(cls, sizes: StepSizes, policy: PolicyConfig, value_streams: int = 1) -> ActorCritic:
        """The networks `policy` describes (its NETWORK_SETTINGS) for steps of `sizes`."""
        return cls(*sizes, **{name: getattr(policy, name) for name in NETWORK_SETTINGS}, value_streams=value_streams)

    def normalize(self, obs: torch.Tensor, critic_obs: torch.Tensor, update: bool) -> tuple[torch.Tensor, torch.Tensor]:
        """Normalised inputs for actor and critic; update=True folds this batch into the statistics first."""
        if not self.normalize_observations:
            return obs, critic_obs
        if update:
            self.obs_normalizer.update(obs)
            self.critic_obs_normalizer.update(critic_obs)
        return self.obs_normalizer(obs), self.critic_obs_normalizer(critic_obs)

    def action_std(self) -> torch.Tensor:
        std = self.std.clamp_min(self.min_std)
        return std if self.max_std is None else torch.minimum(std, self.max_std)

    def distribution(self, norm_obs: torch.Tensor) -> Normal:
        mean = self.actor(norm_obs)
        # No argument validation: it re-checks every batch and costs ~1 % of an update on CPU.
        return Normal(mean, self.action_std().expand_as(mean), validate_args=False)

    def value(self, norm_critic_obs: torch.Tensor) -> torch.Tensor:
        """[B] values, or [B, K] with K value streams."""
        values = self.critic(norm_critic_obs)
        return values.squeeze(-1) if self.value_streams == 1 else values

    def act_deterministic(self, obs: torch.Tensor) -> torch.Tensor:
        """The mean action for raw (unnormalised) observations: what the exported actor computes."""
        norm_obs = self.obs_normalizer(obs) if self.normalize_observations else obs
        return self.actor(norm_obs)

    def architecture(self) -> dict:
        """Everything needed to rebuild this module (stored in checkpoints and the export sidecar); the value
        streams only where there are several, so that the networks saved before streams existed still fit."""
        streams = {'value_streams': self.value_streams} if self.value_streams > 1 else {}
        return {
            'num_obs': self.num_obs,
            'num_critic_obs': self.num_critic_obs,
            'num_actions': self.num_actions,
            'actor_hidden_dims': self.actor_hidden_dims,
            'critic_hidden_dims': self.critic_hidden_dims,
            'activation': self.activation,
            'normalize_observations': self.normalize_observations,
            **streams,
        }


def network_sizes(architecture: dict) -> dict:
    """An architecture without its value streams: what a network must share with a run to start it (the
    critic's streams are fitted, `fit_value_streams`)."""
    return {key: value for key, value in architecture.items() if key != 'value_streams'}


def fit_value_streams(
    state: dict[str, torch.Tensor], architecture: dict, value_streams: int
) -> dict[str, torch.Tensor]:
    """An ActorCritic state of `architecture` with its critic's output layer made value_streams wide, keeping
    the summed value (what the policy follows): a wider critic gives its first stream the old value and the
    new streams 0; a narrower one sums the streams it drops into its last."""
    old = int(architecture.get('value_streams', 1))
    if old == value_streams:
        return state
    head = len(architecture['critic_hidden_dims'])
    weight_key, bias_key = f'critic.{2 * head}.weight', f'critic.{2 * head}.bias'
    fitted = dict(state)
    for key in (weight_key, bias_key):
        rows = state[key]
        if value_streams > old:
            fitted[key] = torch.cat((rows, torch.zeros((value_streams - old, *rows.shape[1:]), dtype=rows.dtype)))
        else:
            fitted[key] = torch.cat((rows[: value_streams - 1], rows[value_streams - 1 :].sum(0, keepdim=True)))
    return fitted
