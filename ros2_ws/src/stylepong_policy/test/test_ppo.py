"""PPO parts on their own (normaliser, GAE, KL, losses, config) and PPO learning a small toy task."""

import math
import pathlib

import numpy as np
import pytest
import torch
from torch.distributions import Normal, kl_divergence

from stylepong_policy.rl.config import TrainConfig, config_from_dict, load_config, save_config
from stylepong_policy.rl.env import StepSizes
from stylepong_policy.rl.networks import ActorCritic, fit_value_streams
from stylepong_policy.rl.normalizer import RunningNormalizer
from stylepong_policy.rl.ppo import PPO, gaussian_kl
from stylepong_policy.rl.runner import OnPolicyRunner, seed_everything
from stylepong_policy.rl.storage import RolloutStorage
from stylepong_policy.training.task import TaskConfig

import ppo_toy_task  # beside this file: conftest.py

HERE = pathlib.Path(__file__).resolve().parent


def toy_config(**ppo) -> TrainConfig:
    return config_from_dict(
        {
            'policy': {'actor_hidden_dims': [64, 64], 'critic_hidden_dims': [64, 64], 'init_noise_std': 0.5},
            'ppo': {**ppo_toy_task.TOY_PPO, **ppo},
            'runner': {'seed': 0, 'save_interval': 1000},
        }
    )


def test_normalizer_matches_batch_statistics_for_any_split():
    rng = np.random.default_rng(0)
    data = rng.normal([1.0, -3.0, 20.0], [0.5, 2.0, 7.0], size=(1000, 3)).astype(np.float32)
    norm = RunningNormalizer(3)
    for chunk in np.split(data, [1, 7, 300, 301, 999]):
        norm.update(torch.from_numpy(chunk))
    np.testing.assert_allclose(norm.mean.numpy(), data.mean(0), rtol=1e-5, atol=1e-5)
    np.testing.assert_allclose(norm.var.numpy(), data.var(0), rtol=1e-4)
    assert float(norm.count) == 1000
    out = norm(torch.from_numpy(data)).numpy()
    np.testing.assert_allclose(out.mean(0), 0.0, atol=1e-4)
    np.testing.assert_allclose(out.std(0), 1.0, atol=1e-3)


def test_normalizer_clips_outliers():
    norm = RunningNormalizer(1, clip=5.0)
    norm.update(torch.randn(10000, 1))
    assert float(norm(torch.tensor([[1e6]]))) == pytest.approx(5.0)


def _storage_with(rewards, dones, values):
    T, N = rewards.shape
    storage = RolloutStorage(T, N, StepSizes(1, 1, 1), 'cpu')
    for t in range(T):
        zeros = torch.zeros(N, 1)
        storage.add(zeros, zeros, zeros, rewards[t], dones[t], values[t], torch.zeros(N), zeros, zeros + 1)
    return storage


def test_gae_with_lambda_one_is_discounted_return_cut_at_episode_ends():
    gamma = 0.9
    rewards = torch.tensor([[1.0], [2.0], [3.0], [4.0]])
    dones = torch.tensor([[0.0], [1.0], [0.0], [0.0]])  # the episode ends after step 1
    values = torch.tensor([[0.5], [0.1], [0.7], [0.2]])
    last_value = torch.tensor([10.0])
    storage = _storage_with(rewards, dones, values)
    storage.compute_returns(last_value, gamma=gamma, lam=1.0, normalize_advantages=False)
    expected = [1.0 + gamma * 2.0, 2.0, 3.0 + gamma * 4.0 + gamma**2 * 10.0, 4.0 + gamma * 10.0]
    np.testing.assert_allclose(storage.returns[:, 0].numpy(), expected, rtol=1e-6)
    np.testing.assert_allclose(storage.advantages[:, 0].numpy(), np.array(expected) - values[:, 0].numpy(), rtol=1e-6)


def test_gae_with_lambda_zero_is_one_step_td_error():
    gamma = 0.99
    rewards = torch.tensor([[1.0, 0.0], [0.5, 2.0]])
    dones = torch.tensor([[0.0, 1.0], [0.0, 0.0]])
    values = torch.tensor([[0.2, 0.3], [0.4, 0.6]])
    last = torch.tensor([1.0, -1.0])
    storage = _storage_with(rewards, dones, values)
    storage.compute_returns(last, gamma=gamma, lam=0.0, normalize_advantages=False)
    expected = torch.tensor([[1.0 + gamma * 0.4 - 0.2, 0.0 - 0.3], [0.5 + gamma * 1.0 - 0.4, 2.0 - gamma * 1.0 - 0.6]])
    torch.testing.assert_close(storage.advantages, expected)


def test_value_streams_each_estimate_their_own_advantage_with_their_own_ends_and_the_policy_follows_the_sum():
    """Two streams on one environment: the second ends after step 0 where the episode goes on, so its reward
    at step 1 does not reach step 0; the first bootstraps through. The advantage is the streams' sum."""
    gamma = 0.9
    storage = RolloutStorage(2, 1, StepSizes(1, 1, 1), 'cpu', value_streams=2)
    rewards = torch.tensor([[[1.0, 0.0]], [[0.0, 5.0]]])
    dones = torch.tensor([[[0.0, 1.0]], [[0.0, 0.0]]])
    values = torch.tensor([[[0.5, 0.0]], [[0.2, 3.0]]])
    zeros = torch.zeros(1, 1)
    for t in range(2):
        storage.add(zeros, zeros, zeros, rewards[t], dones[t], values[t], torch.zeros(1), zeros, zeros + 1)
    storage.compute_returns(torch.tensor([[1.0, 2.0]]), gamma=gamma, lam=1.0, normalize_advantages=False)
    expected = torch.tensor([[[1.0 + gamma * 0.0 + gamma**2 * 1.0, 0.0]], [[gamma * 1.0, 5.0 + gamma * 2.0]]])
    torch.testing.assert_close(storage.returns, expected)
    torch.testing.assert_close(storage.advantages, (expected - values).sum(-1))
    mb = next(storage.minibatches(1, 1))
    assert mb.returns.shape == (2, 2) and mb.advantages.shape == (2,)


def test_an_episode_end_ends_every_value_stream():
    storage = RolloutStorage(1, 3, StepSizes(1, 1, 1), 'cpu', value_streams=2)
    zeros = torch.zeros(3, 1)
    storage.add(
        zeros,
        zeros,
        zeros,
        torch.zeros(3, 2),
        torch.tensor([0.0, 1.0, 0.0]),
        torch.zeros(3, 2),
        torch.zeros(3),
        zeros,
        zeros + 1,
    )
    assert storage.dones[0].tolist() == [[0.0, 0.0], [1.0, 1.0], [0.0, 0.0]]


@pytest.mark.parametrize('streams', [(1, 2), (2, 1), (2, 3)])
def test_a_critic_fitted_to_another_number_of_value_streams_keeps_the_summed_value(streams):
    old, new = streams
    torch.manual_seed(0)
    source = ActorCritic(3, 4, 2, [16, 8], [16, 8], value_streams=old)
    with torch.no_grad():
        for parameter in source.critic.parameters():
            parameter.normal_()
    target = ActorCritic(3, 4, 2, [16, 8], [16, 8], value_streams=new)
    target.load_state_dict(fit_value_streams(source.state_dict(), source.architecture(), new))
    obs = torch.randn(5, 4)
    total = source.value(obs) if old == 1 else source.value(obs).sum(-1)
    fitted = target.value(obs)
    assert fitted.shape == ((5,) if new == 1 else (5, new))
    torch.testing.assert_close(fitted if new == 1 else fitted.sum(-1), total)
    torch.testing.assert_close(target.actor(obs[:, :3]), source.actor(obs[:, :3]))
    assert ('value_streams' in target.architecture()) == (new > 1)


def test_minibatches_cover_every_sample_once_per_epoch():
    T, N = 4, 6
    storage = _storage_with(
        torch.arange(T * N, dtype=torch.float32).reshape(T, N), torch.zeros(T, N), torch.zeros(T, N)
    )
    storage.compute_returns(torch.zeros(N), 0.0, 0.0, normalize_advantages=False)
    seen = sorted(v for mb in storage.minibatches(3, 1) for v in mb.returns.tolist())
    assert seen == list(range(T * N))


def test_gaussian_kl_matches_torch():
    mean_old, mean_new = torch.randn(5, 3), torch.randn(5, 3)
    std_old, std_new = torch.rand(5, 3) + 0.1, torch.rand(5, 3) + 0.1
    expected = kl_divergence(Normal(mean_old, std_old), Normal(mean_new, std_new)).sum(-1)
    torch.testing.assert_close(gaussian_kl(mean_old, std_old, mean_new, std_new), expected)


def _filled_storage(ac: ActorCritic, ppo: PPO, shift_mean: float = 0.0) -> RolloutStorage:
    """One-step episodes whose reward is a smooth function of the critic's input (so V can fit it)."""
    T, N = 4, 32
    storage = RolloutStorage(T, N, StepSizes.of(ac), 'cpu')
    with torch.inference_mode():
        for _ in range(T):
            critic_obs = torch.randn(N, ac.num_critic_obs)
            step = ppo.act(torch.randn(N, ac.num_obs), critic_obs)
            storage.add(
                step.norm_obs,
                step.norm_critic_obs,
                step.actions,
                3.0 * critic_obs.sum(-1),
                torch.ones(N),
                step.values,
                step.log_probs,
                step.mean + shift_mean,
                step.std,
            )
    storage.compute_returns(torch.zeros(N), 0.99, 0.95)
    return storage


def test_adaptive_learning_rate_falls_when_the_policy_moved_far_and_rises_when_it_did_not():
    torch.manual_seed(0)
    cfg = toy_config(num_learning_epochs=1, num_mini_batches=1, learning_rate=1e-3).ppo
    ac = ActorCritic(3, 4, 2, [16], [16])
    ppo = PPO(ac, cfg)
    ppo.update(_filled_storage(ac, ppo, shift_mean=5.0))  # old policy far away: KL >> desired
    assert ppo.learning_rate == pytest.approx(1e-3 / 1.5)
    ac2 = ActorCritic(3, 4, 2, [16], [16])
    ppo2 = PPO(ac2, cfg)
    ppo2.update(_filled_storage(ac2, ppo2, shift_mean=0.01))  # almost the same policy: tiny KL
    assert ppo2.learning_rate == pytest.approx(1e-3 * 1.5)


def test_fixed_and_linear_schedules():
    ac = ActorCritic(3, 4, 2, [8], [8])
    linear = PPO(ac, toy_config(schedule='linear', learning_rate=1e-3, min_learning_rate=1e-5).ppo)
    linear.apply_schedule(50, 100)
    assert linear.learning_rate == pytest.approx(0.5 * (1e-3 + 1e-5))
    fixed = PPO(ac, toy_config(schedule='fixed', learning_rate=2e-4).ppo)
    fixed.update(_filled_storage(ac, fixed, shift_mean=5.0))
    assert fixed.learning_rate == pytest.approx(2e-4)


def test_update_lowers_the_clipped_objective_on_a_fixed_batch():
    torch.manual_seed(1)
    ac = ActorCritic(3, 4, 2, [32], [32])
    ppo = PPO(
        ac,
        toy_config(
            num_learning_epochs=1,
            num_mini_batches=1,
            schedule='fixed',
            learning_rate=1e-2,
            use_clipped_value_loss=False,
        ).ppo,
    )
    storage = _filled_storage(ac, ppo)
    first = ppo.update(storage)
    for _ in range(50):
        last = ppo.update(storage)
    assert last['value_loss'] < 0.5 * first['value_loss']
    assert last['surrogate_loss'] < first['surrogate_loss']


def test_config_rejects_unknown_keys_and_bad_values(tmp_path):
    with pytest.raises(ValueError, match='unknown keys'):
        config_from_dict({'ppo': {'learning_rat': 1e-3}})
    with pytest.raises(ValueError, match='schedule'):
        config_from_dict({'ppo': {'schedule': 'cosine'}})
    with pytest.raises(ValueError, match='gamma'):
        config_from_dict({'ppo': {'gamma': 1.5}})
    with pytest.raises(ValueError, match='unknown config sections'):
        config_from_dict({'algorithm': {}})
    bad = tmp_path / 'bad.yaml'
    bad.write_text('ppo: [1, 2\n')
    with pytest.raises(ValueError, match='not valid YAML'):
        load_config(bad)


def test_config_yaml_round_trip_and_shipped_default(tmp_path):
    cfg = config_from_dict({'policy': {'actor_hidden_dims': [8, 4]}, 'task': {'num_envs': 7, 'anything': [1, 2]}})
    save_config(cfg, tmp_path / 'c.yaml')
    assert load_config(tmp_path / 'c.yaml') == cfg
    shipped = load_config(HERE.parent / 'config' / 'ppo.yaml')
    assert shipped.policy.activation == 'elu'
    assert shipped.runner.seed < 1000


def test_a_config_extends_another_and_changes_only_what_it_names(tmp_path):
    (tmp_path / 'base.yaml').write_text('ppo:\n  gamma: 0.9\n  lam: 0.9\ntask:\n  num_envs: 8\n')
    (tmp_path / 'child.yaml').write_text('extends: base.yaml\nppo:\n  lam: 0.8\n')
    cfg = load_config(tmp_path / 'child.yaml')
    assert (cfg.ppo.gamma, cfg.ppo.lam, cfg.task['num_envs']) == (0.9, 0.8, 8)
    save_config(cfg, tmp_path / 'saved.yaml')  # what a run keeps is whole
    assert 'extends' not in (tmp_path / 'saved.yaml').read_text()
    assert load_config(tmp_path / 'saved.yaml') == cfg
    (tmp_path / 'loop.yaml').write_text('extends: loop.yaml\n')
    with pytest.raises(ValueError, match='extends itself'):
        load_config(tmp_path / 'loop.yaml')
    (tmp_path / 'orphan.yaml').write_text('extends: nowhere.yaml\n')
    with pytest.raises(ValueError, match='cannot read config'):
        load_config(tmp_path / 'orphan.yaml')


def test_every_training_config_in_the_package_loads():
    # The experiment recipes are documented commands: a key misspelt in one fails here, not an hour into a run.
    paths = sorted(p for p in (HERE.parent / 'config').glob('*.yaml') if p.name != 'player.yaml')
    assert {'ppo.yaml', 'amp.yaml'} <= {p.name for p in paths}
    for path in paths:
        cfg = load_config(path)
        cfg.validate()
        assert cfg.runner.seed < 1000, path.name


def test_defaults_are_the_shipped_ppo_yaml():
    # config/ppo.yaml is the source of the dataclass defaults (rl.config's docstring): a section or key a
    # YAML leaves out means what the baseline ran with.
    shipped = load_config(HERE.parent / 'config' / 'ppo.yaml')
    defaults = TrainConfig()
    assert (shipped.policy, shipped.ppo, shipped.runner) == (defaults.policy, defaults.ppo, defaults.runner)
    assert shipped.task['num_envs'] == TaskConfig().num_envs


def toy_success_rate(actor_critic: ActorCritic, toy, episodes_steps: int = 30) -> float:
    """Deterministic policy, fresh env, every env's first episode: the fraction that reached the target."""
    env = toy.ReachTask(num_envs=512, seed=123, episode_steps=episodes_steps)
    obs, _ = env.reset()
    outcome = torch.full((env.num_envs,), -1)
    with torch.inference_mode():
        for _ in range(episodes_steps):
            obs, _, _, dones, info = env.step(actor_critic.act_deterministic(obs))
            first = dones & (outcome < 0)
            outcome[first] = info['success'][first].long()
    assert (outcome >= 0).all()
    return float(outcome.float().mean())


def test_ppo_learns_the_toy_task(tmp_path):
    toy = ppo_toy_task
    seed_everything(0)
    env = toy.ReachTask(num_envs=256, seed=0)
    runner = OnPolicyRunner(env, toy_config(), tmp_path, tensorboard=False)
    before = toy_success_rate(runner.actor_critic, toy)
    stats = runner.learn(40, progress_bar=False)
    after = toy_success_rate(runner.actor_critic, toy)
    assert before < 0.5
    assert after > 0.95, (before, after)
    assert stats['success_rate'] > 0.9, stats
    assert stats['timeout_rate'] == pytest.approx(1.0 - stats['success_rate'])
    assert math.isfinite(stats['final_distance']) and stats['episodes'] > 0
