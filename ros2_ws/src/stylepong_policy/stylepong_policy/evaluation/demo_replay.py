"""Could a demonstrated stroke return a ball? Its joint positions replayed against incoming balls.

A demonstration is dragged without a ball, so nothing in it says whether its stroke would return one,
and a policy that must return balls can only move as close to the demonstrations as strokes that do.
`replay_clip` plays a clip's joint positions, one frame per policy period, as the joint position targets
of the nominal batched world (the servo, contacts and referee that training and `evaluate` use) against
balls of the incoming distribution. A person times a stroke to the ball, so each ball meets the clip at
many start times: the clip's fastest frame (largest joint-speed norm, where the paddle meets the ball in
a demonstration) falls at each of `hit_steps` policy periods after the launch, the clip's first frame
held before it starts and its last after it ends. Each ball keeps its best outcome over the start times.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Sequence

import numpy as np
import torch

from stylepong_sim import referee
from stylepong_sim.batched import batched_launcher, batched_world


@dataclass(frozen=True)
class ReplayOutcome:
    """One clip against `balls` balls, each at every start time."""

    balls: int
    hit: int  # balls the paddle touches at one start time or more
    returned: int  # balls returned (the referee's success) at one start time or more
    hit_verdicts: dict[str, int] = field(default_factory=dict)  # verdicts of every (ball, start) that hit

    @property
    def hit_rate(self) -> float:
        return self.hit / self.balls

    @property
    def return_rate(self) -> float:
        return self.returned / self.balls


def fastest_frame(q_rad: np.ndarray, rate_hz: float) -> int:
    """The frame (after the first) where the joints move fastest: a demonstration's hit."""
    speed = np.linalg.norm(np.diff(np.asarray(q_rad, dtype=float), axis=0), axis=1) * rate_hz
    return int(np.argmax(speed)) + 1


def clip_targets(q_rad: np.ndarray, step: int, hit_steps: torch.Tensor, hit_frame: int) -> torch.Tensor:
    """Joint targets [6, N] at policy step `step` (0: the first period after launch) for start times hit_steps [N]."""
    frames = (step - hit_steps + hit_frame).clamp(0, len(q_rad) - 1)
    return torch.as_tensor(q_rad, dtype=torch.float32)[frames].T


def replay_clip(
    q_rad: np.ndarray,
    balls: int,
    hit_steps: Sequence[int],
    seed: int,
    speed_range_m_s: tuple[float, float],
    max_steps: int = 120,
) -> ReplayOutcome:
    """The clip's joint positions [frames, 6] (policy rate) against `balls` balls of seed `seed`."""
    q_rad = np.asarray(q_rad, dtype=np.float32)
    if q_rad.ndim != 2 or q_rad.shape[1] != 6 or len(q_rad) < 2:
        raise ValueError(f'a clip is (frames >= 2, 6) joint positions, got shape {q_rad.shape}')
    if balls < 1 or not hit_steps:
        raise ValueError('need at least one ball and one start time')
    starts = len(hit_steps)
    n = balls * starts
    world = batched_world.BatchedWorld(n)
    position, velocity, _ = batched_launcher.IncomingBallSampler(speed_range_m_s, seed=seed).sample(balls)
    ball_of_env = torch.arange(n) // starts  # every ball repeated once per start time
    start_q = torch.as_tensor(q_rad[0])[:, None].expand(-1, n)
    world.reset_envs(torch.arange(n), start_q, position[:, ball_of_env], velocity[:, ball_of_env])
    hit_step_of_env = torch.as_tensor(list(hit_steps), dtype=torch.long).repeat(balls)
    hit_frame = fastest_frame(q_rad, 1.0 / world.policy_dt_s)
    decided = torch.zeros(n, dtype=torch.bool)
    success = torch.zeros(n, dtype=torch.bool)
    hit = torch.zeros(n, dtype=torch.bool)
    reason = torch.full((n,), -1, dtype=torch.long)
    for step in range(max_steps):
        events = world.step(clip_targets(q_rad, step, hit_step_of_env, hit_frame))
        now = events.decided & ~decided
        success |= now & events.success
        hit |= now & world.hit
        reason = torch.where(now, events.reason, reason)
        decided |= events.decided
        if bool(decided.all()):
            break
    verdicts = reason[hit]
    return ReplayOutcome(
        balls=balls,
        hit=int(hit.view(balls, starts).any(1).sum()),
        returned=int(success.view(balls, starts).any(1).sum()),
        hit_verdicts={referee.REASONS[int(k)]: int((verdicts == k).sum()) for k in verdicts.unique()},
    )
