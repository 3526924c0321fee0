"""The table-tennis task: interface, seeding, goals, randomisation, rewards and resets."""

import math

import pytest
import torch

from stylepong_player import spec
from stylepong_policy.training import task
from stylepong_sim import referee, world_spec


def _env(n=16, seed=0, **overrides):
    return task.make_env(task.TaskConfig(num_envs=n, **overrides), 'cpu', seed)


def test_interface_shapes_and_types():
    env = _env(8)
    obs, critic = env.reset()
    assert obs.shape == (8, env.num_obs) and critic.shape == (8, env.num_critic_obs)
    assert env.num_actions == 6 and env.device == torch.device('cpu')
    assert env.num_style_features == 12 and env.style_state().shape == (8, 12)
    obs, critic, reward, dones, extras = env.step(torch.zeros(8, 6))
    assert obs.shape == (8, env.num_obs) and critic.shape == (8, env.num_critic_obs)
    assert reward.shape == (8,) and reward.dtype == torch.float32 and dones.dtype == torch.bool
    outcome = extras['outcome']
    for flags in (extras['time_outs'], extras['paddle_hit'], outcome['done'], outcome['success'], outcome['hit']):
        assert flags.shape == (8,) and flags.dtype == torch.bool
    assert outcome['reason'].dtype == torch.int64 and extras['arm_state'].shape == (8, 12)
    assert extras['style_state'] is extras['arm_state'] and extras['ball_state'].shape == (8, 6)
    assert isinstance(extras['log'], dict) and extras['log_weight'] == len(extras['log']) * 0
    assert task.FAILURE_REASONS[task.SUCCESS_INDEX] == referee.REASON_RETURNED
    assert torch.isfinite(obs).all() and torch.isfinite(critic).all()


def test_same_seed_same_episodes_other_seed_others():
    def rollout(seed):
        env = _env(6, seed)
        obs, _ = env.reset()
        generator = torch.Generator().manual_seed(3)
        trace = [obs]
        for _ in range(30):
            obs, _, reward, _, _ = env.step(torch.randn(6, 6, generator=generator))
            trace += [obs, reward[:, None]]
        return torch.cat(trace, dim=1)

    assert torch.equal(rollout(4), rollout(4))
    assert not torch.equal(rollout(4), rollout(5))


def test_goals_lie_on_the_opponents_half_and_are_redrawn_each_episode():
    env = _env(256, randomize=False)
    env.reset()
    goal = env.goal_xy_m.clone()
    r = env.cfg.goal_radius_m
    assert (goal[:, 0] >= r).all() and (goal[:, 0] <= world_spec.HALF_LENGTH_M - r).all()
    assert (goal[:, 1].abs() <= world_spec.HALF_WIDTH_M - r).all()
    assert goal[:, 0].max() - goal[:, 0].min() > 0.5 and goal[:, 1].max() - goal[:, 1].min() > 0.5
    ended = torch.zeros(256, dtype=torch.bool)
    for _ in range(120):
        _, _, _, dones, _ = env.step(torch.zeros(256, 6))
        ended |= dones
        if ended.sum() > 20:
            break
    assert ended.any()
    assert (env.goal_xy_m[ended] != goal[ended]).all(dim=1).all()


def test_domain_randomisation_within_ranges_and_off_when_disabled():
    cfg = task.TaskConfig(num_envs=256)
    env = task.make_env(cfg, 'cpu', 0)
    env.reset()
    p = env.world.params
    for value, bounds in (
        (p.table_restitution, cfg.table_restitution_range),
        (p.paddle_restitution, cfg.paddle_restitution_range),
        (p.gravity_m_s2, cfg.gravity_range_m_s2),
    ):
        assert value.min() >= bounds[0] and value.max() <= bounds[1] and value.std() > 0
    assert env.episode.noise_std.max() > 0 and env.episode.action_delay_physics_steps.max() > 0
    nominal = _env(16, randomize=False)
    nominal.reset()
    assert (nominal.world.params.table_restitution == world_spec.TABLE_RESTITUTION).all()
    assert (nominal.episode.noise_std == 0).all() and (nominal.episode.ball_delay_steps == 0).all()


def test_observation_delay_shows_an_older_ball():
    env = _env(4, randomize=False)
    env.reset()
    for _ in range(5):
        env.step(torch.zeros(4, 6))
    env.episode.ball_delay_steps[:] = torch.tensor([0.0, 1.0, 2.0, 0.5])
    obs, _ = env._observations()
    ball = spec.observation_slice('ball_position_m')
    history = env._ball_history
    torch.testing.assert_close(obs[0, ball], history[0, 0, :3])
    torch.testing.assert_close(obs[1, ball], history[1, 1, :3])
    torch.testing.assert_close(obs[2, ball], history[2, 2, :3])
    torch.testing.assert_close(obs[3, ball], 0.5 * (history[0, 3, :3] + history[1, 3, :3]))


def test_every_action_delay_lets_the_command_reach_the_servo():
    """With any drawn action delay (0..2 physics steps, at most one policy period) a held action reaches the
    servo by the next policy step: no environment's arm is left frozen at its reset pose."""
    env = _env(3, randomize=True, max_action_delay_s=1.0 / 60.0)
    env.reset()
    env.episode.action_delay_physics_steps[:] = torch.arange(3)
    action = torch.tensor([[0.3, -0.2, 0.5, 0.4, -0.5, 0.2]] * 3)
    start = env.world.q_rad.clone()
    for _ in range(2):
        env.step(action)
    target = spec.decode_action(spec.clip_action(action)).to(env.world.q_cmd_rad.dtype)
    torch.testing.assert_close(env.world.q_cmd_rad.T, target)
    assert bool(((env.world.q_rad - start).abs().amax(dim=0) > 1e-3).all())


def _force_return(env, i, start, velocity):
    """Put env i's ball in flight as if the paddle had just struck it."""
    w = env.world
    w.ball_pos_m[:, i] = torch.tensor(start)
    w.ball_vel_m_s[:, i] = torch.tensor(velocity)
    w.hit[i] = True
    w.open[i] = True


def _style_factors_until_verdict(env) -> list[float]:
    """Env 0's style weight factor at each step up to and including its verdict (which must come)."""
    factors = []
    for _ in range(90):
        _, _, _, dones, extras = env.step(torch.zeros(2, 6))
        factors.append(float(extras['style_weight'][0]))
        if dones[0]:
            return factors
    raise AssertionError('no verdict within 1.5 s')


def test_style_weight_factor_holds_from_the_hit_to_the_verdict():
    _, _, _, _, extras = _env(2, randomize=False).step(torch.zeros(2, 6))
    assert 'style_weight' not in extras  # the default: no factor, the same weight throughout
    env = _env(2, randomize=False, style_weight_after_hit=5.0)
    env.reset()
    _, _, _, _, extras = env.step(torch.zeros(2, 6))
    assert extras['style_weight'].tolist() == [1.0, 1.0]  # balls still incoming
    _force_return(env, 0, (-1.0, 0.0, 1.05), (5.0, 0.0, 1.0))
    factors = _style_factors_until_verdict(env)
    assert set(factors) == {5.0}  # every step after the stroke, the verdict's too
    _, _, _, _, extras = env.step(torch.zeros(2, 6))
    assert float(extras['style_weight'][0]) == 1.0  # the next ball starts at the plain weight
    with pytest.raises(ValueError, match='style_weight_after_hit'):
        task.TaskConfig(style_weight_after_hit=-1.0)


def test_style_weight_factor_for_a_fixed_time_after_the_hit():
    env = _env(2, randomize=False, style_weight_after_hit=5.0, style_weight_after_hit_s=0.3)
    env.reset()
    _force_return(env, 0, (-1.0, 0.0, 1.05), (5.0, 0.0, 1.0))
    factors = _style_factors_until_verdict(env)
    assert len(factors) > 18  # the flight outlasts the window
    assert factors[:18] == [5.0] * 18  # 0.3 s at 60 Hz from the stroke
    assert set(factors[18:]) == {1.0}  # a longer flight earns no more of it
    with pytest.raises(ValueError, match='style_weight_after_hit_s'):
        task.TaskConfig(style_weight_after_hit_s=-0.1)


def test_rewards_for_a_return_a_miss_and_illegal_contact():
    env = _env(3, randomize=False)
    env.reset()
    goal = env.goal_xy_m[0]
    _force_return(env, 0, (-1.0, 0.0, 1.05), (5.0, 0.0, 1.0))  # returned over the net
    _force_return(env, 1, (-0.5, 0.0, 0.9), (6.0, 0.0, 0.0))  # into the net
    kin = env.world.kinematics
    forearm = kin.origin_m[:, 2, 2] + 0.5 * (kin.origin_m[:, 3, 2] - kin.origin_m[:, 2, 2])
    env.world.ball_pos_m[:, 2] = forearm + torch.tensor([0.0, 0.0, 0.2])
    env.world.ball_vel_m_s[:, 2] = torch.tensor([0.0, 0.0, -3.0])
    totals = torch.zeros(3)
    outcome = [None] * 3
    for _ in range(90):
        _, _, reward, dones, info = env.step(torch.zeros(3, 6))
        for i in range(3):
            if outcome[i] is None:
                totals[i] += reward[i]
                if dones[i]:
                    outcome[i] = (
                        task.FAILURE_REASONS[int(info['outcome']['reason'][i])],
                        bool(info['outcome']['success'][i]),
                        float(info['reward_terms']['success'][i]),
                        float(info['reward_terms']['illegal'][i]),
                    )
        if all(o is not None for o in outcome):
            break
    assert outcome[0][:2] == (referee.REASON_RETURNED, True) and outcome[0][2] == env.cfg.w_success
    assert outcome[1][:2] == (referee.REASON_NET, False) and outcome[1][2] == 0.0 and outcome[1][3] == 0.0
    assert outcome[2][:2] == (referee.REASON_ROBOT_CONTACT, False) and outcome[2][3] == -env.cfg.w_illegal
    assert totals[0] > totals[1] > totals[2]
    del goal


def test_regularisation_terms_only_ever_lower_the_reward():
    env = _env(64)
    env.reset()
    generator = torch.Generator().manual_seed(0)
    for _ in range(30):
        _, _, _, _, info = env.step(3.0 * torch.randn(64, 6, generator=generator))
        terms = info['reward_terms']
        for name in ('acc', 'dof', 'rate', 'action', 'illegal', 'command'):
            assert (terms[name] <= 0).all(), name
        for name in ('bat', 'hit', 'goal', 'land', 'success'):
            assert (terms[name] >= 0).all(), name
    # At rest at home with a zero action the regularisation costs nothing.
    still = _env(2, randomize=False)
    still.reset()
    _, _, _, _, info = still.step(torch.zeros(2, 6))
    for name in ('dof', 'rate', 'action'):
        assert info['reward_terms'][name].abs().max() < 1e-6, name


def test_a_command_below_the_table_top_costs_w_command_per_step_and_nothing_by_default():
    into = torch.zeros(2, 6)
    into[1, 1] = 0.9 / spec.ACTION_SCALE_RAD[1]  # shoulder lift down and elbow stretched, env 1 only
    into[1, 2] = -0.6 / spec.ACTION_SCALE_RAD[2]
    for weight, expected in ((0.0, [0.0, 0.0]), (1.5, [0.0, -1.5])):
        env = _env(2, randomize=False, w_command=weight)
        env.reset()
        _, _, _, _, info = env.step(into)
        assert info['reward_terms']['command'].tolist() == pytest.approx(expected), weight


def test_done_envs_restart_with_a_new_ball_and_the_arm_near_home():
    env = _env(32, randomize=False)
    env.reset()
    seen = False
    for _ in range(150):
        obs, _, _, dones, info = env.step(torch.ones(32, 6) * 0.3)
        if dones.any():
            seen = True
            i = int(torch.nonzero(dones)[0])
            assert float(env.world.time_s[i]) == 0.0 and bool(env.world.open[i])
            assert not bool(env.world.hit[i])
            home = torch.tensor(spec.HOME_JOINT_POSITIONS_RAD)
            torch.testing.assert_close(
                obs[i, spec.observation_slice('joint_position_offset_rad')], env.world.q_rad[:, i] - home
            )
            ball_x_m = obs[i, spec.observation_slice('ball_position_m')][0]
            assert ball_x_m > 0.5  # the new ball starts on the opponent's side
            assert (obs[i, spec.observation_slice('last_action')] == 0).all()  # no previous action in a new episode
            break
    assert seen


def test_timeouts_are_reported_for_bootstrapping():
    env = _env(2, randomize=False, episode_length_s=0.25)
    env.reset()
    env.world.params.gravity_m_s2[:] = 0.0
    env.world.ball_vel_m_s[:] = 0.0
    for _ in range(20):
        _, _, _, dones, info = env.step(torch.zeros(2, 6))
        if dones.any():
            break
    assert dones.all() and info['time_outs'].all()
    assert task.FAILURE_REASONS[int(info['outcome']['reason'][0])] == referee.REASON_TIMEOUT
    assert info['log_weight'] == 2 and info['log']['ball/timeout'] == 1.0 and info['log']['success_rate'] == 0.0


def test_style_frames_are_the_arm_state_before_a_reset_and_after_it():
    """The contract's 'style_state' is the frame an ended episode reached; style_state() is the new
    episode's first frame, so the motion prior never sees a window spanning two episodes."""
    env = _env(2, randomize=False, episode_length_s=0.1)
    env.reset()
    for _ in range(20):
        _, _, _, dones, extras = env.step(torch.full((2, 6), 0.3))
        if dones.any():
            break
    assert dones.all()
    home = torch.tensor(spec.HOME_JOINT_POSITIONS_RAD)
    assert (extras['style_state'][:, :6] - home).abs().max() > 0.05  # moved towards the target
    torch.testing.assert_close(env.style_state()[:, :6], home.expand(2, -1))  # reset to home


def test_launch_velocity_is_the_episodes_ball_at_launch():
    env = _env(4, randomize=False)
    env.reset()
    torch.testing.assert_close(env.launch_velocity_m_s, env.world.ball_vel_m_s.T)
    speed = torch.linalg.vector_norm(env.launch_velocity_m_s, dim=1)
    assert ((speed >= env.cfg.speed_range_m_s[0] - 1e-4) & (speed <= env.cfg.speed_range_m_s[1] + 1e-4)).all()


def test_config_validation():
    with pytest.raises(ValueError):
        task.TaskConfig(num_envs=0)
    with pytest.raises(ValueError):
        task.TaskConfig(speed_range_m_s=(6.0, 4.0))
    with pytest.raises(ValueError):
        task.TaskConfig(bat_axes='w')
    cfg = task.TaskConfig(speed_range_m_s=[4.0, 4.8])  # YAML gives lists
    assert cfg.speed_range_m_s == (4.0, 4.8)
    assert math.isclose(task.TaskConfig().goal_radius_m, 0.25)


def test_aim_credits_a_stroke_towards_the_goal_only_over_the_net():
    env = _env(3, randomize=False)
    env.reset()
    env.episode.goal_xy_m[:] = torch.tensor([0.8, 0.0])
    w = env.world
    w.ball_pos_m[:] = torch.tensor([[-1.3, 0.0, 1.0]] * 3).T
    # Drag-free: 4 m/s forward for 0.525 s lands on the goal; vz from z(T) = table + radius.
    t = 2.1 / 4.0
    vz = (world_spec.TABLE_CONTACT_HEIGHT_M - 1.0 + 0.5 * world_spec.GRAVITY_M_S2 * t * t) / t
    w.ball_vel_m_s[:] = torch.tensor([[4.0, 0.0, vz], [-4.0, 0.0, vz], [6.0, 0.0, -1.0]]).T
    quality = env._aim_quality(torch.ones(3, dtype=torch.bool))
    assert quality[0] > 0.99 and quality[1] == 0.0 and quality[2] == 0.0  # over, away, into the net
    assert (env._aim_quality(torch.zeros(3, dtype=torch.bool)) == 0).all()


def test_bad_actions_are_refused_with_a_clear_error():
    env = _env(2)
    env.reset()
    with pytest.raises(ValueError, match='NaN'):
        env.step(torch.tensor([[0.0] * 6, [float('nan')] + [0.0] * 5]))
    with pytest.raises(ValueError, match='shape'):
        env.step(torch.zeros(2, 5))
    env.step(torch.zeros(2, 6))  # and the env still works


def test_each_step_asks_for_the_stroke_its_ball_needs_as_evaluate_labels_it():
    """'style_label' (rl.env): the index into strokes.DIRECTIONS of where the ball will reach the robot, known
    from its launch. Balls that fly past an arm held at home cross the paddle's home plane at the y that
    strokes.direction_of labels the same way, in the nominal and in the randomised world (drag, gravity and
    restitution change the flight, not its heading)."""
    from stylepong_policy.evaluation import strokes

    plane_x_m, home_y_m, _ = strokes.paddle_home_position_m()
    for randomize in (False, True):
        env = _env(256, seed=3, randomize=randomize, reset_joint_noise_rad=0.0)
        env.reset()
        assert env.style_labels == strokes.DIRECTIONS
        asked = env.episode.direction.clone()
        crossed = torch.full((256,), math.nan, dtype=torch.float64)
        touched = torch.zeros(256, dtype=torch.bool)
        done = torch.zeros(256, dtype=torch.bool)
        previous = env.ball_position_m.clone().double()
        for _ in range(150):
            _, _, _, dones, extras = env.step(torch.zeros(256, 6))
            label = extras['style_label']
            live = ~done
            assert torch.equal(label[live], asked[live])  # the episode's label, before its reset
            now = extras['ball_state'][:, :3].double()
            through = live & torch.isnan(crossed) & (previous[:, 0] > plane_x_m) & (now[:, 0] <= plane_x_m)
            share = (previous[:, 0] - plane_x_m) / (previous[:, 0] - now[:, 0])
            crossed = torch.where(through, previous[:, 1] + share * (now[:, 1] - previous[:, 1]), crossed)
            touched |= live & extras['paddle_hit']
            done |= dones
            previous = env.ball_position_m.clone().double()
            if done.all():
                break
        checked = ~torch.isnan(crossed) & ~touched
        assert int(checked.sum()) > 150
        expected = [strokes.DIRECTIONS.index(strokes.direction_of(float(y), home_y_m)) for y in crossed[checked]]
        agree = (asked[checked] == torch.tensor(expected)).float().mean()
        assert agree > 0.98, (randomize, float(agree))  # a ball a hair from a threshold may fall either side
        assert set(asked.tolist()) == {0, 1, 2}


def test_each_step_s_phase_turns_at_the_paddle_s_first_touch_of_its_ball():
    """'style_phase' (rl.env): 0 until the paddle first touches the episode's ball, 1 from that step to the
    verdict, before the reset; a new episode starts at 0 again."""
    env = _env(256, seed=4, reset_joint_noise_rad=0.0)
    env.reset()
    touched = torch.zeros(256, dtype=torch.bool)
    ended_after_touch = 0
    for _ in range(150):
        _, _, _, dones, extras = env.step(torch.zeros(256, 6))
        touched |= extras['paddle_hit']
        assert torch.equal(extras['style_phase'], touched.long())
        ended_after_touch += int((dones & touched).sum())
        touched &= ~dones
    # an arm held at home meets enough balls for this to say something
    assert ended_after_touch > 10, ended_after_touch


def test_the_style_clock_counts_down_to_the_ball_and_up_from_the_touch_and_the_stroke_ends_once():
    """'style_time_s' (rl.env): before the touch, minus the time the ball needs at its speed along x to
    reach the paddle's home plane; from the touch, the time since it. 'style_stroke_end': once, 0.3 s
    after the touch, as evaluate cuts strokes."""
    env = _env(2, randomize=False)
    env.reset()
    _, _, _, _, extras = env.step(torch.zeros(2, 6))
    w = env.world
    expected = -(w.ball_pos_m[0] - env._plane_x_m) / (-w.ball_vel_m_s[0])
    assert torch.allclose(extras['style_time_s'], expected)
    assert bool((extras['style_time_s'] < 0).all()) and not bool(extras['style_stroke_end'].any())
    _force_return(env, 0, (-1.0, 0.0, 1.05), (5.0, 0.0, 1.0))
    clock, ends = [], []
    for _ in range(19):
        _, _, _, dones, extras = env.step(torch.zeros(2, 6))
        clock.append(float(extras['style_time_s'][0]))
        ends.append(bool(extras['style_stroke_end'][0]))
        assert not dones[0]
    assert clock[:3] == pytest.approx([1 / 60, 2 / 60, 3 / 60])
    assert ends == [False] * 17 + [True, False]  # the 18th step after the touch: 0.3 s
