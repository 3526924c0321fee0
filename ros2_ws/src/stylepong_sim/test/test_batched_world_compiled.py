"""SLOW (about a minute, most of it torch.compile's compilation): the compiled batched world is the eager one.

The PPO baseline was trained with TaskConfig.compile_world (BatchedWorld(compile=True): torch.compile of
its kinematics, arm dynamics, arm step and ball step) and is evaluated in the eager world; this holds
only if both step the same physics. Both worlds start from the same states, get the same commands for
1.5 s, and must end in the same states (float32 rounding apart) with the same hits and verdicts. Half
of the balls come from the incoming-ball distribution while the arm swings; the other half are thrown
at the paddle, so that paddle contacts are among the compiled code paths compared.
"""

import math

import pytest
import torch

from stylepong_sim import world_spec
from stylepong_sim.batched import batched_launcher, batched_world

NUM_ENVS = 64
STEPS = 90  # 1.5 s at the 60 Hz policy rate: every ball is decided by then
# float32 worlds whose operations are fused and reordered by the compiler differ by rounding only
# (measured: 7e-7 rad, 2e-6 m after 90 steps); a real difference in the physics is far larger.
ATOL = {'q_rad': 1e-4, 'qd_rad_s': 1e-3, 'ball_pos_m': 1e-4, 'ball_vel_m_s': 1e-3, 'landing_xy_m': 1e-4}


def _run(world: batched_world.BatchedWorld) -> tuple[dict, torch.Tensor, torch.Tensor]:
    generator = torch.Generator().manual_seed(5)
    ids = torch.arange(NUM_ENVS)
    home = torch.tensor(world_spec.HOME_JOINT_POSITIONS_RAD)[:, None].repeat(1, NUM_ENVS)
    start_q = home + 0.05 * torch.randn(6, NUM_ENVS, generator=generator)
    position, velocity, _ = batched_launcher.IncomingBallSampler(seed=3, batch=256).sample(NUM_ENVS)
    world.reset_envs(ids, start_q, position.float(), velocity.float())
    # The second half: balls thrown at the paddle from about 0.6 m in front of it.
    half = NUM_ENVS // 2
    paddle = world.paddle_pos_m[:, half:].clone()
    thrown_from = (
        paddle + torch.tensor([0.6, 0.0, 0.1])[:, None] + 0.05 * torch.randn(3, NUM_ENVS - half, generator=generator)
    )
    world.ball_pos_m[:, half:] = thrown_from
    world.ball_vel_m_s[:, half:] = (paddle - thrown_from) / 0.15
    amplitude = 0.4 * torch.rand(6, NUM_ENVS, generator=generator)
    frequency_hz = 0.5 + 2.0 * torch.rand(6, NUM_ENVS, generator=generator)
    hits = torch.zeros(NUM_ENVS, dtype=torch.long)
    decided_at = torch.full((NUM_ENVS,), -1)
    for k in range(STEPS):
        events = world.step(start_q + amplitude * torch.sin(2.0 * math.pi * frequency_hz * k * world.policy_dt_s))
        hits += events.paddle_hit.long()
        decided_at = torch.where(events.decided, k, decided_at)
    state = {name: getattr(world, name).clone() for name in ATOL}
    state.update(reason=world.reason.clone(), success=world.success.clone(), open=world.open.clone())
    return state, hits, decided_at


@pytest.mark.slow
def test_compiled_world_steps_the_same_physics_as_the_eager_world():
    eager, eager_hits, eager_decided = _run(batched_world.BatchedWorld(NUM_ENVS))
    compiled, compiled_hits, compiled_decided = _run(batched_world.BatchedWorld(NUM_ENVS, compile=True))
    # The comparison means something: paddle contacts happened and every rally was decided.
    assert int((eager_hits > 0).sum()) >= 8
    assert not bool(eager['open'].any())
    for name, atol in ATOL.items():
        torch.testing.assert_close(compiled[name], eager[name], rtol=0.0, atol=atol, msg=lambda m: f'{name}: {m}')
    assert torch.equal(compiled_hits, eager_hits)
    assert torch.equal(compiled_decided, eager_decided)
    assert torch.equal(compiled['reason'], eager['reason'])
    assert torch.equal(compiled['success'], eager['success'])
