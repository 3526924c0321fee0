"""The runner's checkpoints, resume, logs and interruption handling, on the toy task."""

import csv

import pytest
import torch

from stylepong_policy.rl.config import config_from_dict
from stylepong_policy.rl.logger import plot_learning_curve, read_progress
from stylepong_policy.rl.runner import OnPolicyRunner, read_checkpoint, seed_everything

import ppo_toy_task as TOY  # beside this file: conftest.py


def small_config(**runner):
    return config_from_dict(
        {
            'policy': {'actor_hidden_dims': [32, 32], 'critic_hidden_dims': [32, 32], 'init_noise_std': 1.0},
            'ppo': {'num_steps_per_env': 8, 'num_mini_batches': 2, 'num_learning_epochs': 2, 'entropy_coef': 0.005},
            'runner': {'seed': 3, 'save_interval': 2, 'keep_checkpoints': 2, **runner},
        }
    )


def make_runner(run_dir, cfg=None, tensorboard=False, env=None):
    env = env or TOY.ReachTask(num_envs=64, seed=5)
    return OnPolicyRunner(env, cfg or small_config(), run_dir, tensorboard=tensorboard)


def test_resume_continues_exactly_like_an_uninterrupted_run(tmp_path):
    """Model, optimiser, normalisers, learning rate and every RNG come back from the checkpoint."""
    seed_everything(3)
    straight = make_runner(tmp_path / 'a')
    straight.learn(3, progress_bar=False)
    env_rng_at_3 = straight.env.generator.get_state()
    straight.learn(6, progress_bar=False)

    seed_everything(99)  # a fresh process would have other RNG states: the checkpoint must restore them
    env = TOY.ReachTask(num_envs=64, seed=5)
    env.generator.set_state(env_rng_at_3)  # the toy env's own state is not part of the runner's checkpoint
    resumed = make_runner(tmp_path / 'b', env=env)
    resumed.load(tmp_path / 'a' / 'checkpoints' / 'model_000004.pt')  # an older one first: overwritten next
    resumed.load(tmp_path / 'a')  # a run dir means its last.pt
    assert resumed.iteration == 6
    checkpoint = read_checkpoint(tmp_path / 'a' / 'checkpoints' / 'last.pt')
    assert checkpoint['iteration'] == 6

    # Rewind both to iteration 3 of run a and continue: identical parameters at the end.
    seed_everything(3)
    straight = make_runner(tmp_path / 'c')
    straight.learn(3, progress_bar=False)
    straight.save(tmp_path / 'at3.pt')
    env_rng_at_3 = straight.env.generator.get_state()
    straight.learn(6, progress_bar=False)

    seed_everything(99)
    env = TOY.ReachTask(num_envs=64, seed=5)
    env.generator.set_state(env_rng_at_3)
    resumed = make_runner(tmp_path / 'd', env=env)
    resumed.load(tmp_path / 'at3.pt')
    assert (resumed.iteration, resumed.env_steps) == (3, 3 * 8 * 64)
    resumed.learn(6, progress_bar=False)
    for (name, a), b in zip(straight.actor_critic.state_dict().items(), resumed.actor_critic.state_dict().values()):
        torch.testing.assert_close(a, b, msg=f'{name} differs after resume')
    assert resumed.alg.learning_rate == straight.alg.learning_rate
    assert resumed.wall_time_s > 0 and len(resumed.sessions) == 2


def test_checkpoint_files_csv_and_tensorboard(tmp_path):
    runner = make_runner(tmp_path, tensorboard=True)
    runner.learn(5, progress_bar=False)
    checkpoints = sorted(p.name for p in (tmp_path / 'checkpoints').iterdir())
    assert checkpoints == ['last.pt', 'model_000002.pt', 'model_000004.pt']
    runner.learn(7, progress_bar=False)
    assert sorted(p.name for p in (tmp_path / 'checkpoints').iterdir()) == [
        'last.pt',
        'model_000004.pt',
        'model_000006.pt',
    ]  # keep_checkpoints=2
    progress = read_progress(tmp_path / 'progress.csv')
    assert progress['iteration'] == [1, 2, 3, 4, 5, 6, 7]
    for column in ('samples_per_s', 'world_share', 'success_rate', 'timeout_rate', 'kl', 'value_loss'):
        assert column in progress
    assert list((tmp_path / 'tensorboard').glob('events.out.tfevents.*'))
    plot_learning_curve(tmp_path / 'progress.csv', tmp_path / 'curve.png')
    assert (tmp_path / 'curve.png').stat().st_size > 10_000


def test_a_slim_checkpoint_resumes_with_its_model_and_a_fresh_optimiser(tmp_path):
    """A checkpoint stripped to the model and its records (optimiser and RNG states dropped) still resumes."""
    seed_everything(3)
    run = make_runner(tmp_path / 'a')
    run.learn(2, progress_bar=False)
    slim = read_checkpoint(tmp_path / 'a' / 'checkpoints' / 'last.pt')
    slim.update(optimizer=None, rng=None, motion_prior=None)
    torch.save(slim, tmp_path / 'slim.pt')
    resumed = make_runner(tmp_path / 'b')
    resumed.load(tmp_path / 'slim.pt')
    assert resumed.iteration == 2
    for a, b in zip(run.actor_critic.state_dict().values(), resumed.actor_critic.state_dict().values()):
        assert torch.equal(a, b)
    assert not resumed.alg.optimizer.state  # fresh: no Adam moments yet
    resumed.learn(3, progress_bar=False)
    assert resumed.iteration == 3


def test_resume_from_an_older_checkpoint_rewrites_the_csv_history(tmp_path):
    make_runner(tmp_path).learn(5, progress_bar=False)
    again = make_runner(tmp_path)
    again.load(tmp_path / 'checkpoints' / 'model_000004.pt')
    again.learn(6, progress_bar=False)
    with open(tmp_path / 'progress.csv', newline='') as f:
        iterations = [int(row['iteration']) for row in csv.DictReader(f)]
    assert iterations == [1, 2, 3, 4, 5, 6]
    assert read_checkpoint(tmp_path)['iteration'] == 6


def test_load_refuses_other_networks_and_damaged_files(tmp_path):
    make_runner(tmp_path / 'run').learn(1, progress_bar=False)
    bigger = small_config()
    bigger.policy.actor_hidden_dims = [64, 32]
    with pytest.raises(ValueError, match='actor_hidden_dims'):
        make_runner(tmp_path / 'other', cfg=bigger).load(tmp_path / 'run')
    damaged = tmp_path / 'damaged.pt'
    damaged.write_bytes((tmp_path / 'run' / 'checkpoints' / 'last.pt').read_bytes()[:1000])
    with pytest.raises(ValueError, match='not a readable checkpoint'):
        make_runner(tmp_path / 'x').load(damaged)
    with pytest.raises(FileNotFoundError):
        make_runner(tmp_path / 'y').load(tmp_path / 'nowhere')


class InterruptingTask(TOY.ReachTask):
    """Raises KeyboardInterrupt (a Ctrl-C) in the middle of a given iteration's rollout."""

    def __init__(self, interrupt_at_step: int, **kwargs):
        super().__init__(**kwargs)
        self.interrupt_at_step = interrupt_at_step
        self.calls = 0

    def step(self, actions):
        self.calls += 1
        if self.calls == self.interrupt_at_step:
            raise KeyboardInterrupt
        return super().step(actions)


def test_ctrl_c_keeps_the_last_completed_iteration(tmp_path):
    env = InterruptingTask(interrupt_at_step=8 * 3 + 4, num_envs=64, seed=5)  # inside iteration 4
    runner = make_runner(tmp_path, env=env)
    runner.learn(10, progress_bar=False)
    assert runner.interrupted and runner.iteration == 3
    assert read_checkpoint(tmp_path)['iteration'] == 3
    assert not list((tmp_path / 'checkpoints').glob('*.tmp'))


def test_non_finite_env_output_stops_training(tmp_path):
    class NanTask(TOY.ReachTask):
        def step(self, actions):
            obs, critic_obs, rewards, dones, info = super().step(actions)
            rewards[0] = float('nan')
            return obs, critic_obs, rewards, dones, info

    runner = make_runner(tmp_path, env=NanTask(num_envs=16, seed=0))
    with pytest.raises(FloatingPointError, match='non-finite'):
        runner.learn(1, progress_bar=False)


def test_episode_statistics_weight_the_env_log_by_the_episodes_it_averages():
    """The env's 'log' is a mean over the episodes that ended in a step; an iteration's figure is the mean
    over all its episodes, so a step where three ended counts three times one where one ended."""
    from stylepong_policy.rl.runner import EpisodeStatistics

    stats = EpisodeStatistics(3, torch.device('cpu'))

    def step(done, log=None):
        done = torch.tensor(done)
        extras = {'time_outs': torch.zeros(3, dtype=torch.bool), 'log': log or {}, 'log_weight': int(done.sum())}
        stats.record(torch.ones(3), done, extras)

    step([False, False, False])
    step([True, True, False], {'success_rate': 0.5})
    step([False, False, True], {'success_rate': 0.0})
    step([True, False, False], {'success_rate': 1.0})
    summary = stats.summary()
    assert summary['episodes'] == 4
    assert summary['success_rate'] == pytest.approx((2 * 0.5 + 0.0 + 1.0) / 4)
    assert summary['mean_return'] == pytest.approx((2 + 2 + 3 + 2) / 4)


@pytest.mark.parametrize('keep', [False, True])
def test_a_run_from_a_skill_keeps_its_std_as_the_ceiling_when_asked(tmp_path, keep):
    """A heavy entropy bonus widens the noise; with keep_skill_std the skill's std caps it, across a resume."""
    seed_everything(3)
    skill = make_runner(tmp_path / 'skill')
    skill.learn(2, progress_bar=False)
    skill_std = skill.actor_critic.action_std().detach().clone()
    cfg = config_from_dict(
        {
            'policy': {
                'actor_hidden_dims': [32, 32],
                'critic_hidden_dims': [32, 32],
                'init_noise_std': 1.0,
                'keep_skill_std': keep,
            },
            'ppo': {'num_steps_per_env': 8, 'num_mini_batches': 2, 'num_learning_epochs': 2, 'entropy_coef': 1.0},
            'runner': {'seed': 3, 'save_interval': 2, 'keep_checkpoints': 2},
        }
    )
    run = make_runner(tmp_path / 'run', cfg)
    run.start_from(tmp_path / 'skill')
    run.learn(4, progress_bar=False)
    wider = (run.actor_critic.action_std() > skill_std + 1e-6).any()
    assert bool(wider) != keep
    resumed = make_runner(tmp_path / 'resumed', cfg)
    resumed.load(tmp_path / 'run')
    assert (resumed.actor_critic.max_std is not None) == keep
