"""The batched-environment contract the runner, PPO and the motion prior are written against.

Like rsl_rl's VecEnv: N environments stepped together on tensors, each resetting itself when its
episode ends. Nothing here knows what the task is; the table-tennis task (stylepong_policy.training.task) and the
toy task of the tests both follow it.

Sizes: `num_envs`, `num_obs` (the actor's input), `num_critic_obs` (the critic's, privileged),
`num_actions`, `num_style_features` (one frame of the state the style discriminator sees: positions
followed by as many velocities, as a reference dataset's states()); `device`.

`reset() -> (obs [N, num_obs], critic_obs [N, num_critic_obs])` starts every environment afresh.

`step(actions [N, num_actions]) -> (obs, critic_obs, rewards [N], dones [N] bool, extras)`: ended
episodes are already reset, so obs are the new episodes' first observations. `extras` holds
  'time_outs'    [N] bool: episodes cut by a time limit rather than ended by the task (the runner
                 bootstraps their value instead of treating them as terminal);
  'log'          {name: float}: statistics of the episodes that ended in this step, each the mean over
                 them (empty when none ended); the runner averages them over an iteration weighted by
  'log_weight'   int: how many episodes 'log' averages;
  'style_state'  [N, num_style_features]: the frame the style discriminator sees, after the step and
                 before any reset (so the last frame of an ended episode is still its own).
and may hold
  'style_weight' [N] float: a factor on this step's style weight, for an env that knows where in an
                 episode the motion matters more (absent: 1 everywhere);
  'style_label'  [N] int64: which kind of motion each step should be, an index into the env's
                 `style_labels` (the demonstrations' labels it knows), before any reset; a motion prior
                 conditioned on labels (amp.condition_on_label) needs it;
  'style_phase'  [N] int64: 0 before the event that splits each episode's motion in two (the task: the
                 paddle's first touch of the ball), 1 from it on, before any reset; a motion prior
                 conditioned on phases (amp.condition_on_phase) needs it;
  'style_time_s' [N] float: the style clock, the time from each step to that event (negative before it,
                 the time it is expected in; positive after it), before any reset; the pose prior
                 (amp.w_pose, rl.pose_prior) needs it;
  'style_stroke_end' [N] bool: the step that ends the stroke each episode's style is judged on (the
                 episode's end ends it too, if nothing did before), before any reset; the stroke prior
                 (amp.w_stroke, rl.stroke_prior) needs it.
An env may add keys of its own for its own tools (the table-tennis task adds per-ball outcomes for
`evaluate`); the runner reads only these.

`style_state() -> [N, num_style_features]`: the current frame (after resets), so that a new episode's
style history starts from its own first frame.

An env whose stroke goes on a fixed time after the event gives it as `style_follow_through_s` (float);
the pose prior's follow-through (amp.pose_follows_through) needs it.
"""

from __future__ import annotations

from typing import Any, NamedTuple, Protocol

import torch

EXTRAS_TIME_OUTS = 'time_outs'
EXTRAS_LOG = 'log'
EXTRAS_LOG_WEIGHT = 'log_weight'
EXTRAS_STYLE_STATE = 'style_state'
EXTRAS_STYLE_WEIGHT = 'style_weight'
EXTRAS_STYLE_LABEL = 'style_label'
EXTRAS_STYLE_PHASE = 'style_phase'
EXTRAS_STYLE_TIME = 'style_time_s'
EXTRAS_STYLE_STROKE_END = 'style_stroke_end'


class StepSizes(NamedTuple):
    """The widths of one step's records: the actor's observation, the critic's and the action."""

    num_obs: int
    num_critic_obs: int
    num_actions: int

    @classmethod
    def of(cls, source: Any) -> StepSizes:
        """The sizes of a VecEnv, an ActorCritic or anything else with the three attributes."""
        return cls(int(source.num_obs), int(source.num_critic_obs), int(source.num_actions))


class VecEnv(Protocol):
    """The batched environment the runner trains on."""

    num_envs: int
    num_obs: int
    num_critic_obs: int
    num_actions: int
    num_style_features: int
    device: torch.device

    def reset(self) -> tuple[torch.Tensor, torch.Tensor]: ...

    def step(
        self, actions: torch.Tensor
    ) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor, torch.Tensor, dict[str, Any]]: ...

    def style_state(self) -> torch.Tensor: ...
