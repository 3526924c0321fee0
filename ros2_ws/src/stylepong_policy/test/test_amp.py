"""The adversarial motion prior (stylepong_policy.rl.amp): reference windows, history, replay, the
discriminator's loss and what it learns, the style reward, and AMP training on the toy task."""

import math
import pathlib

import numpy as np
import pytest
import torch
from synthetic_reference import one_clip_dataset

from stylepong_policy.rl.amp import (
    MotionPrior,
    ReferenceMotion,
    ReplayBuffer,
    StyleHistory,
    feature_columns,
    style_reward,
)
from stylepong_policy.rl.config import AMPConfig, TrainConfig, config_from_dict
from stylepong_policy.rl.runner import OnPolicyRunner, seed_everything
from stylepong_policy.training.dataset import ReferenceDataset

import ppo_toy_task as TOY  # beside this file: conftest.py

BAGS = pathlib.Path(__file__).resolve().parents[3] / 'bags'


def test_reference_windows_never_cross_a_clip_and_are_drawn_uniformly():
    frames = np.arange(10, dtype=float)[:, None] * np.ones((1, 2))
    reference = ReferenceMotion(frames, clip_starts=[0, 4, 9], clip_lengths=[4, 5, 1], length=3)
    assert reference.num_windows == 2 + 3  # the 1-frame clip has none
    windows = reference.sample(20000, torch.Generator().manual_seed(0))
    first = windows[:, 0, 0].long()
    assert set(first.tolist()) == {0, 1, 4, 5, 6}
    counts = torch.bincount(first, minlength=7)[[0, 1, 4, 5, 6]].float()
    assert (counts / counts.sum() - 0.2).abs().max() < 0.02
    assert torch.equal(windows[:, 1:, 0] - windows[:, :-1, 0], torch.ones(20000, 2))  # consecutive frames


def test_style_history_restarts_a_new_episode_from_its_own_first_frame():
    history = StyleHistory(torch.zeros(2, 1), length=3)
    history.push(torch.tensor([[1.0], [1.0]]))
    windows = history.push(torch.tensor([[2.0], [2.0]]))
    assert windows[:, :, 0].tolist() == [[0.0, 1.0, 2.0]] * 2
    history.restart(torch.tensor([1]), torch.tensor([[9.0]]))
    windows = history.push(torch.tensor([[3.0], [10.0]]))
    assert windows[:, :, 0].tolist() == [[1.0, 2.0, 3.0], [9.0, 9.0, 10.0]]


def test_replay_buffer_keeps_the_most_recent_windows():
    buffer = ReplayBuffer(5, (1, 1), 'cpu')
    for start in (0, 3, 6):
        buffer.insert(torch.arange(start, start + 3, dtype=torch.float32).reshape(3, 1, 1))
    assert buffer.size == 5
    assert sorted(buffer.data.flatten().tolist()) == [4.0, 5.0, 6.0, 7.0, 8.0]
    assert set(buffer.sample(200, torch.Generator().manual_seed(1)).flatten().tolist()) <= {4.0, 5.0, 6.0, 7.0, 8.0}


def test_style_rewards_are_bounded_and_rise_with_the_discriminator_output():
    d = torch.linspace(-3.0, 3.0, 61)
    for kind in ('lsgan', 'log'):
        r = style_reward(d, kind)
        assert r.min() >= 0.0 and r.max() <= 1.0 + 1e-6
        assert r[d <= -1.0].max() == 0.0  # the policy target earns nothing
        rising = r[(d >= -1.0) & (d <= 1.0)]
        assert (rising[1:] >= rising[:-1]).all() and rising[-1] > 0.99
    assert style_reward(torch.tensor([1.0]))[0] == 1.0 and style_reward(torch.tensor([0.0]))[0] == 0.75
    with pytest.raises(ValueError):
        style_reward(d, 'bce')


def _shipped_or_synthetic_dataset(tmp_path) -> ReferenceDataset:
    """The dataset of the shipped clips; a synthetic swing set where the bags are not there."""
    if any(BAGS.glob('*/metadata.yaml')):
        from stylepong_policy.training import build_dataset

        assert build_dataset.run([str(BAGS), '-o', str(tmp_path / 'd.npz')]) == 0
        return ReferenceDataset.load(tmp_path / 'd.npz')
    from stylepong_policy.training.dataset import Clip, SourceClip, assemble_dataset

    t = np.arange(120) / 60.0
    originals = []
    for i in range(4):
        phase = 2.0 * np.pi * (t / 2.0) + 0.3 * i
        q = 0.6 * np.sin(phase)[:, None] * np.linspace(0.5, 1.0, 6)[None, :]
        qd = 0.6 * np.pi * np.cos(phase)[:, None] * np.linspace(0.5, 1.0, 6)[None, :]
        originals.append(SourceClip(Clip(t=t, q=q, qd=qd), label='forward', source=f'synthetic{i}'))
    return assemble_dataset(originals, (2, 3, 5), [f'j{i}' for i in range(6)], 60.0)


def _slowed(windows: torch.Tensor, reference: ReferenceMotion) -> torch.Tensor:
    """The same motions played at half speed: every second window frame repeated is too crude, so take
    windows over half-spaced frames by interpolating the reference and halving the velocities."""
    starts = reference.starts[torch.randint(reference.num_windows, (windows.shape[0],))].float()
    times = starts[:, None] + 0.5 * torch.arange(reference.length)[None, :].float()
    lower = times.floor().long().clamp(max=reference.frames.shape[0] - 2)
    frac = (times - lower)[..., None]
    frames = reference.frames[lower] * (1 - frac) + reference.frames[lower + 1] * frac
    half = frames.shape[-1] // 2
    return torch.cat((frames[..., :half], 0.5 * frames[..., half:]), dim=-1)


MOVING_RAD_S = 0.3  # a window's mean joint speed (norm over joints); 80 % of the shipped clips' windows


def _mean_joint_speed(windows: torch.Tensor) -> torch.Tensor:
    """[B, L, 12] (q, qdot) windows -> [B]: the norm of qdot, averaged over the window's frames."""
    return windows[..., windows.shape[-1] // 2 :].norm(dim=-1).mean(dim=1)


@pytest.mark.slow  # over 7 s on the 2-core machine: .ci/run runs it, `make test` skips it
@pytest.mark.parametrize('negative', ['shuffled', 'slowed'])
def test_the_discriminator_separates_reference_windows_from_shuffled_or_slowed_ones(tmp_path, negative):
    """LSGAN training against windows whose frames are shuffled among the demonstrations (every pose is
    right, the motion is not) or which are the demonstrations played at half speed: on fresh samples D
    puts the reference above 0 and the fakes below."""
    torch.manual_seed(0)
    dataset = _shipped_or_synthetic_dataset(tmp_path)
    cfg = AMPConfig(sequence_length=5, batch_size=512, updates_per_iteration=1, grad_penalty=1.0)
    # Slowed: against the original clips only, since half of an x2 clip's speed is its original's.
    speeds = [1] if negative == 'slowed' else None
    reference = ReferenceMotion.from_dataset(dataset, cfg.sequence_length, speeds)
    prior = MotionPrior(cfg, reference, frame_size=12, num_envs=1, device='cpu', seed=0)

    def fakes(count):
        if negative == 'shuffled':
            # Each frame from its own random reference window: every frame is a demonstrated state, but
            # the sequence is no motion, so only the frames' order and coherence give it away.
            frames = [reference.sample(count)[:, i] for i in range(cfg.sequence_length)]
            return torch.stack(frames, dim=1)
        return _slowed(reference.sample(count), reference)

    # Shuffled windows are told apart early (accuracy 0.99, mean scores +0.77 / -0.76 after 150 updates,
    # measured); half-speed ones are the harder case and keep 300.
    for _ in range(150 if negative == 'shuffled' else 300):
        prior.replay.size = 0
        prior.replay.insert(fakes(cfg.batch_size))
        stats = prior.update()
    references, fake_windows = reference.sample(4000), fakes(4000)
    if negative == 'slowed':
        # Where the arm (nearly) rests, half its speed is the same motion: a dragged take creeps off the
        # ready pose and turns at the end of its back-swing. Scored where the demonstration moves.
        references = references[_mean_joint_speed(references) > MOVING_RAD_S]
        fake_windows = fake_windows[_mean_joint_speed(fake_windows) > 0.5 * MOVING_RAD_S]
    with torch.no_grad():
        d_reference = prior.discriminator.score(references)
        d_fake = prior.discriminator.score(fake_windows)
    accuracy = 0.5 * ((d_reference > 0).float().mean() + (d_fake < 0).float().mean())
    assert accuracy > 0.85, (negative, float(accuracy), stats)
    assert d_reference.mean() > 0.2 and d_fake.mean() < -0.2  # on their sides of 0, towards the targets +-1


def test_position_features_keep_only_the_joint_positions_of_reference_and_policy_frames():
    """frame_features 'q': the reference windows, the replayed policy windows and the windows scored for the
    reward hold the first half of each (positions, velocities) frame, in order."""
    frames = np.arange(40 * 4, dtype=np.float64).reshape(40, 4)  # 2 joints: q0 q1 qd0 qd1
    dataset = one_clip_dataset(frames[:, :2], frames[:, 2:], 'forward')
    cfg = AMPConfig(sequence_length=3, frame_features='q', batch_size=8, updates_per_iteration=1)
    reference = ReferenceMotion.from_dataset(dataset, cfg.sequence_length, features='q')
    assert torch.equal(reference.windows(torch.tensor([0]))[0], torch.tensor(frames[:3, :2], dtype=torch.float32))
    prior = MotionPrior(cfg, reference, frame_size=4, num_envs=2, device='cpu')
    policy = torch.tensor([[1.0, 2.0, 30.0, 40.0], [5.0, 6.0, 70.0, 80.0]])
    prior.start(policy)
    prior.observe(policy + 1.0, torch.tensor([False, True]), policy)
    assert torch.equal(prior.replay.data[:2, -1], policy[:, :2] + 1.0)
    assert torch.equal(prior.history.frames[1], policy[1, :2].expand(3, 2))  # restarted from its new first frame
    assert prior.discriminator.normalizer.mean.shape[-1] == 2
    assert 'disc/loss' in prior.update()
    with pytest.raises(ValueError, match='reference frames hold 4'):
        MotionPrior(cfg, ReferenceMotion.from_dataset(dataset, 3), frame_size=4, num_envs=1, device='cpu')
    with pytest.raises(ValueError, match='not positions and velocities'):
        feature_columns('q', 5)
    with pytest.raises(ValueError, match='unknown frame features'):
        feature_columns('qdd', 4)


def test_loss_and_gradient_penalty_see_the_same_normalised_inputs():
    """The penalty is the gradient of D with respect to the normalised reference windows the loss used:
    for a linear discriminator it is exactly |w|^2, whatever the normaliser's statistics."""
    cfg = AMPConfig(
        sequence_length=2, hidden_dims=[], batch_size=64, updates_per_iteration=1, grad_penalty=1.0, learning_rate=1e-12
    )
    frames = np.random.default_rng(0).normal(3.0, 5.0, size=(50, 3))
    reference = ReferenceMotion(frames, [0], [50], 2)
    prior = MotionPrior(cfg, reference, frame_size=3, num_envs=1, device='cpu')
    prior.replay.insert(reference.sample(64))
    weight = prior.discriminator.head.weight.detach().clone()
    stats = prior.update()
    assert stats['disc/grad_penalty'] == pytest.approx(float(weight.square().sum()), rel=1e-4)


def _tiny_prior_config(num_steps_per_env: int, runner: dict | None = None, **amp) -> TrainConfig:
    """Policy, critic and discriminator of one 8-unit layer, windows of 2 frames: enough to watch how the
    runner mixes and streams the rewards, not to learn; `runner` and `amp` add to or override its settings."""
    return config_from_dict(
        {
            'policy': {'actor_hidden_dims': [8], 'critic_hidden_dims': [8]},
            'ppo': {'num_steps_per_env': num_steps_per_env},
            'runner': {'seed': 0, 'save_interval': 1000, **(runner or {})},
            'amp': {'sequence_length': 2, 'hidden_dims': [8], 'batch_size': 64, 'replay_size': 1000, **amp},
        }
    )


def test_an_env_style_factor_scales_the_style_weight_per_environment(tmp_path):
    """The runner passes the env's 'style_weight' extras to the mix: a style-only reward with the factor 0
    in every environment returns nothing, with the factor 2 twice what it does without one."""
    cfg = _tiny_prior_config(40, w_task=0.0, w_style=1.0)

    class FactorTask(TOY.ReachTask):
        def __init__(self, factor):
            super().__init__(num_envs=16, seed=0, episode_steps=10)
            self.factor = factor

        def step(self, actions):
            obs, critic_obs, rewards, dones, extras = super().step(actions)
            if self.factor is not None:
                extras['style_weight'] = torch.full((self.num_envs,), self.factor)
            return obs, critic_obs, rewards, dones, extras

    returns = {}
    for factor in (None, 0.0, 2.0):
        seed_everything(0)
        env = FactorTask(factor)
        reference = ReferenceMotion(np.random.default_rng(0).normal(size=(50, 4)), [0], [50], 2)
        prior = MotionPrior(cfg.amp, reference, env.num_style_features, env.num_envs, 'cpu', seed=0)
        runner = OnPolicyRunner(env, cfg, tmp_path / str(factor), tensorboard=False, motion_prior=prior)
        returns[factor] = runner.learn(1, progress_bar=False)
    assert returns[None]['mean_return'] > 0.0 and returns[0.0]['mean_return'] == 0.0
    assert math.isclose(returns[2.0]['mean_return'], 2.0 * returns[None]['mean_return'], rel_tol=1e-5)
    assert returns[2.0]['step_reward/style'] == returns[None]['step_reward/style']  # logged unweighted


def test_a_held_run_scales_the_motion_terms_down_when_its_returns_fall_and_resumes_with_that_scale(tmp_path):
    """amp.hold_success: the runner feeds each iteration's training success to rl.success_hold, and the
    scale it returns weighs the next iteration's motion terms (a style-only reward returns nothing at
    scale 0); a resumed run continues at the saved scale."""
    cfg = _tiny_prior_config(
        40,
        runner={'critic_warmup_iterations': 2},
        w_task=0.0,
        w_style=1.0,
        hold_success=True,
        hold_success_gain=100.0,
        hold_success_smoothing=1.0,
    )

    class FallingTask(TOY.ReachTask):
        """Reports every episode a success for the first two iterations' worth of steps, then none."""

        def step(self, actions):
            obs, critic_obs, rewards, dones, extras = super().step(actions)
            self.calls = getattr(self, 'calls', 0) + 1
            if extras['log']:
                extras['log']['success_rate'] = 1.0 if self.calls <= 2 * 40 else 0.0
            return obs, critic_obs, rewards, dones, extras

    seed_everything(0)
    env = FallingTask(num_envs=16, seed=0, episode_steps=10)
    reference = ReferenceMotion(np.random.default_rng(0).normal(size=(50, 4)), [0], [50], 2)
    prior = MotionPrior(cfg.amp, reference, env.num_style_features, env.num_envs, 'cpu', seed=0)
    runner = OnPolicyRunner(env, cfg, tmp_path / 'run', tensorboard=False, motion_prior=prior)
    warm = runner.learn(2, progress_bar=False)
    assert warm['motion_scale'] == 1.0 and warm['mean_return'] > 0.0
    fallen = runner.learn(3, progress_bar=False)  # its success 0: far below the floor
    assert fallen['motion_scale'] == 0.0 and prior.motion_scale == 0.0
    assert runner.learn(4, progress_bar=False)['mean_return'] == 0.0
    runner.save(tmp_path / 'held.pt')
    again = MotionPrior(cfg.amp, reference, env.num_style_features, env.num_envs, 'cpu', seed=0)
    resumed = OnPolicyRunner(env, cfg, tmp_path / 'resumed', tensorboard=False, motion_prior=again)
    resumed.load(tmp_path / 'held.pt')
    assert again.motion_scale == 0.0 and resumed.success_hold.floor == pytest.approx(0.97)


class TouchTask(TOY.ReachTask):
    """The toy task with a touch: 'style_phase' is 1 from an episode's third step on; its target is out of
    reach, so that every episode ends at its step limit (as a terminal, so no value is bootstrapped)."""

    def _reset_envs(self, idx):
        super()._reset_envs(idx)
        self.target[idx] = self.position[idx] + 10.0

    def step(self, actions):
        obs, critic_obs, rewards, dones, extras = super().step(actions)
        extras['style_phase'] = ((self.steps >= 3) | dones).long()  # an ended episode's steps are reset
        extras['time_outs'] = torch.zeros_like(dones)
        return obs, critic_obs, rewards, dones, extras


def test_a_free_follow_through_leaves_the_motion_after_the_touch_unheld_in_a_value_stream_that_ends_at_it(tmp_path):
    """amp.free_follow_through: with the motion terms held at 0 a style-only reward still pays the steps that
    began after the touch, in the second value stream alone, and that stream ends at the step that touches."""
    cfg = _tiny_prior_config(12, w_task=0.0, w_style=1.0, free_follow_through=True)
    seed_everything(0)
    env = TouchTask(num_envs=4, seed=0, episode_steps=6)
    reference = ReferenceMotion(np.random.default_rng(0).normal(size=(50, 4)), [0], [50], 2)
    prior = MotionPrior(cfg.amp, reference, env.num_style_features, env.num_envs, 'cpu', seed=0)
    runner = OnPolicyRunner(env, cfg, tmp_path / 'run', tensorboard=False, motion_prior=prior)
    prior.motion_scale = 0.0
    runner.learn(1, progress_bar=False)
    storage = runner.storage
    assert runner.actor_critic.value_streams == 2 and storage.values.shape == (12, 4, 2)
    assert float(storage.rewards[..., 0].abs().max()) == 0.0  # held at 0: nothing before the touch
    # Episodes of 6 steps from a common start: steps 4-6 of each began after the touch (step 3 touches).
    step_in_episode = torch.arange(12) % 6
    after = (step_in_episode >= 3)[:, None].expand(12, 4)
    assert bool((storage.rewards[..., 1][after] > 0).all()) and float(storage.rewards[..., 1][~after].abs().max()) == 0
    touches = (step_in_episode == 2)[:, None].expand(12, 4)
    ends = (step_in_episode == 5)[:, None].expand(12, 4)
    assert bool((storage.dones[..., 1] == (touches | ends).float()).all())
    assert bool((storage.dones[..., 0] == ends.float()).all())


def test_a_free_follow_through_run_starts_from_a_skill_with_one_value_stream(tmp_path):
    """A skill saved with one value stream starts a free follow-through run: the same actor, and a critic
    whose streams sum to the skill's value."""
    small = {
        'policy': {'actor_hidden_dims': [8], 'critic_hidden_dims': [8]},
        'ppo': {'num_steps_per_env': 4},
        'runner': {'seed': 0, 'save_interval': 1000},
    }
    seed_everything(0)
    env = TouchTask(num_envs=4, seed=0, episode_steps=6)
    skill = OnPolicyRunner(env, config_from_dict(small), tmp_path / 'skill', tensorboard=False)
    skill.learn(1, progress_bar=False)
    cfg = config_from_dict(
        {
            **small,
            'amp': {
                'sequence_length': 2,
                'hidden_dims': [8],
                'batch_size': 64,
                'replay_size': 1000,
                'free_follow_through': True,
            },
        }
    )
    reference = ReferenceMotion(np.random.default_rng(0).normal(size=(50, 4)), [0], [50], 2)
    prior = MotionPrior(cfg.amp, reference, env.num_style_features, env.num_envs, 'cpu', seed=0)
    run = OnPolicyRunner(env, cfg, tmp_path / 'run', tensorboard=False, motion_prior=prior)
    run.start_from(tmp_path / 'skill')
    obs, critic_obs = torch.randn(4, env.num_obs), torch.randn(4, env.num_critic_obs)
    with torch.no_grad():
        torch.testing.assert_close(run.actor_critic.act_deterministic(obs), skill.actor_critic.act_deterministic(obs))
        norm = skill.actor_critic.critic_obs_normalizer(critic_obs)
        torch.testing.assert_close(run.actor_critic.value(norm).sum(-1), skill.actor_critic.value(norm))
    run.learn(1, progress_bar=False)


def test_a_free_follow_through_needs_the_env_s_phase(tmp_path):
    cfg = _tiny_prior_config(4, free_follow_through=True)
    env = TOY.ReachTask(num_envs=4, seed=0, episode_steps=6)
    reference = ReferenceMotion(np.random.default_rng(0).normal(size=(50, 4)), [0], [50], 2)
    prior = MotionPrior(cfg.amp, reference, env.num_style_features, env.num_envs, 'cpu', seed=0)
    runner = OnPolicyRunner(env, cfg, tmp_path / 'run', tensorboard=False, motion_prior=prior)
    with pytest.raises(ValueError, match='free_follow_through.*style_phase'):
        runner.learn(1, progress_bar=False)


@pytest.mark.slow  # over 7 s on the 2-core machine: .ci/run runs it, `make test` skips it
def test_style_reward_rises_as_the_policy_imitates_a_clip_on_the_toy_task(tmp_path):
    """AMP alone (no task reward) on the toy task, the reference a steady motion at 0.06 per step along
    +x: the style reward per step rises and the policy ends up moving like the clip."""
    seed_everything(0)
    # 64 clips of 20 frames from random starts in the task's square: the style is the motion, not where.
    rng = np.random.default_rng(0)
    starts = rng.uniform(-1.0, 1.0, size=(64, 1, 2))
    positions = starts + np.stack([0.06 * np.arange(20), np.zeros(20)], axis=1)[None]
    velocities = np.broadcast_to(np.array([0.06, 0.0]), positions.shape)
    frames = np.concatenate([positions, velocities], axis=2).reshape(-1, 4)
    cfg = config_from_dict(
        {
            'policy': {'actor_hidden_dims': [32, 32], 'critic_hidden_dims': [32, 32], 'init_noise_std': 0.5},
            'ppo': {**TOY.TOY_PPO},
            'runner': {'seed': 0, 'save_interval': 1000},
            'amp': {
                'sequence_length': 3,
                'hidden_dims': [32, 32],
                'batch_size': 512,
                'updates_per_iteration': 4,
                'learning_rate': 1e-3,
                'grad_penalty': 1.0,
                'w_task': 0.0,
                'w_style': 1.0,
                'replay_size': 20000,
            },
        }
    )
    env = TOY.ReachTask(num_envs=128, seed=0, episode_steps=30)
    reference = ReferenceMotion(frames, np.arange(64) * 20, [20] * 64, cfg.amp.sequence_length)
    prior = MotionPrior(cfg.amp, reference, env.num_style_features, env.num_envs, 'cpu', seed=0)
    runner = OnPolicyRunner(env, cfg, tmp_path, tensorboard=False, motion_prior=prior)
    first = runner.learn(1, progress_bar=False)['step_reward/style']
    last = runner.learn(60, progress_bar=False)['step_reward/style']
    assert last > first + 0.2, (first, last)
    with torch.inference_mode():
        obs, _ = env.reset()
        velocity = runner.actor_critic.act_deterministic(obs).clamp(-1, 1) * env.step_size
    assert velocity[:, 0].mean() > 0.03 and velocity[:, 1].abs().mean() < 0.03, velocity.mean(0)


def _conditioned_discriminator_config(**condition) -> AMPConfig:
    """A small discriminator on 4-frame windows, learning fast, conditioned as told (label or phase)."""
    return AMPConfig(
        sequence_length=4,
        hidden_dims=[32, 32],
        batch_size=256,
        updates_per_iteration=1,
        grad_penalty=0.1,
        learning_rate=1e-3,
        **condition,
    )


def _train_against_the_wrong_conditions(
    prior: MotionPrior, windows: torch.Tensor, wrong: torch.Tensor, steps: int = 300
) -> None:
    """Train D with the demonstrated windows as its positives and the same windows under the wrong
    condition as the policy's (the replay buffer holds only those)."""
    for _ in range(steps):
        prior.replay.size = 0
        prior.replay.insert(windows, wrong)
        prior.update()


def test_a_discriminator_conditioned_on_labels_tells_a_motion_under_its_own_label_from_it_under_another():
    """condition_on_label: two kinds of demonstrated motion (label 0 rises, label 1 falls). The policy's
    windows are the same motions with the labels swapped: every window is a demonstrated one, only asked
    for in the wrong situation. A conditioned D learns to put each motion above 0 under its own label and
    below 0 under the other; the unconditioned D cannot tell the two sets apart."""
    torch.manual_seed(0)
    ramp = np.linspace(0.0, 1.0, 30)[:, None] * np.ones((1, 2))
    frames = np.concatenate([ramp, ramp[::-1]])  # clip 0 rises, clip 1 falls
    labels = ('up', 'down')
    reference = ReferenceMotion(frames, [0, 30], [30, 30], 4, clip_labels=[0, 1], label_names=labels)
    assert reference.labels.tolist() == [0] * 27 + [1] * 27
    outputs = {}
    for conditioned in (True, False):
        cfg = _conditioned_discriminator_config(condition_on_label=conditioned)
        prior = MotionPrior(cfg, reference, frame_size=2, num_envs=1, device='cpu', seed=0)
        everything = torch.arange(reference.num_windows)
        swapped = 1 - reference.labels[everything]
        _train_against_the_wrong_conditions(prior, reference.windows(everything), swapped)
        with torch.no_grad():
            own = prior.discriminator.score(reference.windows(everything), reference.labels if conditioned else None)
            other = prior.discriminator.score(reference.windows(everything), swapped if conditioned else None)
        outputs[conditioned] = (own, other)
    own, other = outputs[True]
    assert (own > 0).float().mean() > 0.9 and (other < 0).float().mean() > 0.9, (own, other)
    own, other = outputs[False]
    assert float((own - other).abs().max()) == 0.0 and abs(float(own.mean())) < 0.3


def test_a_conditioned_prior_needs_labelled_windows_and_each_step_s_label(tmp_path):
    frames = np.random.default_rng(0).normal(size=(20, 2))
    cfg = AMPConfig(sequence_length=2, hidden_dims=[8], batch_size=8, condition_on_label=True)
    with pytest.raises(ValueError, match='needs reference windows with labels'):
        MotionPrior(cfg, ReferenceMotion(frames, [0], [20], 2), frame_size=2, num_envs=1, device='cpu')
    prior = MotionPrior(
        cfg,
        ReferenceMotion(frames, [0], [20], 2, clip_labels=[1], label_names=('a', 'b')),
        frame_size=2,
        num_envs=2,
        device='cpu',
    )
    prior.start(torch.zeros(2, 2))
    with pytest.raises(ValueError, match='style_label'):
        prior.observe(torch.ones(2, 2), torch.tensor([False, False]), torch.ones(2, 2))
    prior.observe(torch.ones(2, 2), torch.tensor([False, False]), torch.ones(2, 2), torch.tensor([0, 1]))
    assert prior.replay.conditions[:2].tolist() == [0, 1]
    dataset = one_clip_dataset(frames[:, :1], frames[:, 1:], 'sideways')
    with pytest.raises(ValueError, match="labelled \\['sideways'\\]"):
        ReferenceMotion.from_dataset(dataset, 2, label_names=('forward', 'leftward'))
    assert ReferenceMotion.from_dataset(dataset, 2, label_names=('forward', 'sideways')).labels.unique().tolist() == [1]
    with pytest.raises(ValueError, match='condition_on_label'):
        AMPConfig(condition_on_label='yes').validate()


def test_a_reference_window_s_phase_is_its_last_frame_s_and_the_condition_pairs_label_and_phase():
    frames = np.arange(12, dtype=float)[:, None] * np.ones((1, 2))
    after = np.zeros(12, dtype=bool)
    after[[4, 5, 9, 10, 11]] = True  # clip 0 (frames 0-5) hits at 4, clip 1 (6-11) at 9
    reference = ReferenceMotion(
        frames, [0, 6], [6, 6], 3, clip_labels=[0, 1], label_names=('a', 'b'), frame_after_hit=after
    )
    assert reference.phases.tolist() == [0, 0, 1, 1] + [0, 1, 1, 1]  # windows ending at 2-5 and 8-11
    with pytest.raises(ValueError, match='one flag per frame'):
        ReferenceMotion(frames, [0], [12], 3, frame_after_hit=after[:-1])
    labels, phases = torch.tensor([0, 0, 1, 1]), torch.tensor([0, 1, 0, 1])

    def prior(**conditions) -> MotionPrior:
        return MotionPrior(
            AMPConfig(sequence_length=3, hidden_dims=[8], **conditions),
            reference,
            frame_size=2,
            num_envs=1,
            device='cpu',
        )

    both = prior(condition_on_label=True, condition_on_phase=True)
    assert both.num_conditions == 4 and both.condition(labels, phases).tolist() == [0, 1, 2, 3]
    phase_only = prior(condition_on_phase=True)
    assert phase_only.num_conditions == 2 and phase_only.condition(None, phases).tolist() == [0, 1, 0, 1]
    label_only = prior(condition_on_label=True)
    assert label_only.condition(labels, phases).tolist() == [0, 0, 1, 1]
    phase_only.start(torch.zeros(1, 2))
    with pytest.raises(ValueError, match='style_phase'):
        phase_only.observe(torch.ones(1, 2), torch.tensor([False]), torch.ones(1, 2))
    with pytest.raises(ValueError, match='condition_on_phase'):
        AMPConfig(condition_on_phase=1).validate()


def test_a_discriminator_conditioned_on_the_phase_tells_a_follow_through_from_a_swing():
    """condition_on_phase: a clip rises to its hit and falls after it. The policy's windows are the same
    rising and falling windows asked for in the other phase (rising after the hit, falling before it).
    D conditioned on the phase puts each above 0 in its own phase and below 0 in the other."""
    torch.manual_seed(0)
    ramp = np.linspace(0.0, 1.0, 30)[:, None] * np.ones((1, 2))
    frames = np.concatenate([ramp, ramp[::-1]])
    after = np.arange(60) >= 30
    reference = ReferenceMotion(frames, [0], [60], 4, frame_after_hit=after)
    rising = reference.phases == 0
    cfg = _conditioned_discriminator_config(condition_on_phase=True)
    prior = MotionPrior(cfg, reference, frame_size=2, num_envs=1, device='cpu', seed=0)
    everything = torch.arange(reference.num_windows)
    straddling = (everything + 3 >= 30) & (everything < 30)  # windows that hold both phases' frames
    keep = everything[~straddling]
    wrong = 1 - reference.phases[keep]
    _train_against_the_wrong_conditions(prior, reference.windows(keep), wrong)
    with torch.no_grad():
        own = prior.discriminator.score(reference.windows(keep), reference.phases[keep])
        other = prior.discriminator.score(reference.windows(keep), wrong)
    assert rising[keep].any() and (~rising[keep]).any()
    assert (own > 0).float().mean() > 0.9 and (other < 0).float().mean() > 0.9, (own, other)


def test_a_prior_saved_without_phases_resumes_with_them_and_starts_as_it_was():
    """split_phases: a discriminator conditioned on labels, widened to (label, phase), gives every window
    in either phase the output it gave under its label; the resumed prior trains on from there."""
    frames = np.random.default_rng(1).normal(size=(40, 2))
    after = np.arange(40) % 20 >= 12
    reference = ReferenceMotion(
        frames, [0, 20], [20, 20], 3, clip_labels=[0, 1], label_names=('a', 'b'), frame_after_hit=after
    )
    base = dict(sequence_length=3, hidden_dims=[16, 8], batch_size=32, condition_on_label=True)
    saved = MotionPrior(AMPConfig(**base), reference, frame_size=2, num_envs=1, device='cpu', seed=0)
    saved.replay.insert(reference.sample(64), torch.randint(2, (64,)))
    saved.update()
    resumed = MotionPrior(
        AMPConfig(**base, condition_on_phase=True), reference, frame_size=2, num_envs=1, device='cpu', seed=0
    )
    resumed.load_state_dict(saved.state_dict())
    windows, labels = reference.windows(torch.arange(reference.num_windows)), reference.labels
    with torch.no_grad():
        before = saved.discriminator.score(windows, labels)
        for phase in (0, 1):
            now = resumed.discriminator.score(windows, resumed.condition(labels, torch.full_like(labels, phase)))
            assert torch.allclose(now, before, atol=1e-6)
    resumed.replay.insert(reference.sample(64), torch.randint(4, (64,)))
    assert math.isfinite(resumed.update()['disc/loss'])
    with pytest.raises(RuntimeError, match='size mismatch'):  # a phase-conditioned D does not shrink back
        saved.load_state_dict(resumed.state_dict())
