"""rally_eval serves, for seed S, exactly the balls `evaluate` plays for S (the task's first balls)."""

import numpy as np

from stylepong_policy.training import task
from stylepong_sim import world_spec
from stylepong_sim.nodes import rally_eval


def test_rally_eval_balls_are_the_evaluation_balls_of_the_seed():
    for speed in ('all', 'high'):
        cfg = task.TaskConfig(num_envs=6, randomize=False, speed_range_m_s=tuple(world_spec.SPEED_RANGES_M_S[speed]))
        env = task.make_env(cfg, 'cpu', 901)
        env.reset()
        positions, velocities = rally_eval.balls_for_seed(901, 6, speed)
        np.testing.assert_allclose(positions, env.world.ball_pos_m.T.double().numpy(), atol=1e-6)
        np.testing.assert_allclose(velocities, env.world.ball_vel_m_s.T.double().numpy(), atol=1e-6)


def test_goals_lie_on_the_opponents_half_with_their_region():
    goals = rally_eval.goals_for_seed(3, 500)
    r = world_spec.GOAL_RADIUS_M
    assert (goals[:, 0] >= r).all() and (goals[:, 0] <= world_spec.HALF_LENGTH_M - r).all()
    assert (np.abs(goals[:, 1]) <= world_spec.HALF_WIDTH_M - r).all()
    assert task.TaskConfig().goal_radius_m == r  # the task rewards the region rally_eval sends
