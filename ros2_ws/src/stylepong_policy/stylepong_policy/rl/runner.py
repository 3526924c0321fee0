"""The on-policy runner: rollouts in a batched env, PPO updates (with a motion prior's style reward when
one is given), checkpoints with resume, logs.

The env follows the batched-env contract of stylepong_policy.rl.env; nothing else about it is assumed,
so any env with that interface trains here (the tests use a small toy task). What the env counts about
its episodes reaches the logs through the contract's 'log'.
"""

from __future__ import annotations

import math
import os
import pathlib
import random
import sys
import time
from collections import deque
from typing import Any, Callable

import numpy as np
import torch

from . import env as env_contract
from .amp import MotionPrior
from .config import TrainConfig, config_to_dict
from .logger import TrainingLog
from .networks import ActorCritic, fit_value_streams, network_sizes
from .ppo import PPO
from .storage import RolloutStorage
from .success_hold import SuccessHold

CHECKPOINT_FORMAT = 'stylepong-ppo-checkpoint'
CHECKPOINT_VERSION = 1
CHECKPOINT_DIR = 'checkpoints'
LAST_CHECKPOINT = 'last.pt'


def seed_everything(seed: int) -> None:
    """Seed Python's, numpy's and torch's random generators."""
    random.seed(seed)
    np.random.seed(seed % 2**32)
    torch.manual_seed(seed)


def capture_rng_state(shuffle: torch.Generator) -> dict[str, Any]:
    """Every random generator's state (for a checkpoint), loadable with weights_only=True."""
    np_state = np.random.get_state()
    state = {
        'torch': torch.get_rng_state(),
        'python': random.getstate(),
        'shuffle': shuffle.get_state(),
        # numpy's MT19937 state as tensors and ints, so checkpoints load with weights_only=True.
        'numpy': {
            'keys': torch.from_numpy(np_state[1].astype(np.int64)),
            'pos': int(np_state[2]),
            'has_gauss': int(np_state[3]),
            'cached_gaussian': float(np_state[4]),
        },
    }
    if torch.cuda.is_available():
        state['cuda'] = torch.cuda.get_rng_state_all()
    return state


def restore_rng_state(state: dict[str, Any], shuffle: torch.Generator) -> None:
    """Restore the random generators from capture_rng_state's dict."""
    torch.set_rng_state(state['torch'].cpu())
    random.setstate(_as_python_random_state(state['python']))
    shuffle.set_state(state['shuffle'].cpu())
    n = state['numpy']
    np.random.set_state(
        ('MT19937', n['keys'].numpy().astype(np.uint32), n['pos'], n['has_gauss'], n['cached_gaussian'])
    )
    if 'cuda' in state and torch.cuda.is_available() and len(state['cuda']) == torch.cuda.device_count():
        torch.cuda.set_rng_state_all([s.cpu() for s in state['cuda']])


def _as_python_random_state(state):
    # torch.save keeps tuples, but be tolerant of lists (e.g. a checkpoint rewritten by other tools).
    version, internal, gauss = state
    return (version, tuple(internal), gauss)


def describe_device(device: torch.device | str) -> str:
    """Where training ran, in words (the shipped summary must say whether it was this CPU or a GPU)."""
    device = torch.device(device)
    if device.type == 'cuda':
        return f'cuda: {torch.cuda.get_device_name(device)}'
    cpu = 'unknown CPU'
    try:
        with open('/proc/cpuinfo') as f:
            cpu = next((line.split(':', 1)[1].strip() for line in f if line.startswith('model name')), cpu)
    except OSError:
        pass
    return f'cpu: {os.cpu_count()} cores ({cpu}), {torch.get_num_threads()} torch threads'


def find_checkpoint(path: str | pathlib.Path) -> pathlib.Path:
    """A checkpoint file, or the last checkpoint of a run directory."""
    path = pathlib.Path(path)
    if path.is_dir():
        for candidate in (path / CHECKPOINT_DIR / LAST_CHECKPOINT, path / LAST_CHECKPOINT):
            if candidate.is_file():
                return candidate
        raise FileNotFoundError(
            f'no checkpoint in run directory {path} (looked for {CHECKPOINT_DIR}/{LAST_CHECKPOINT})'
        )
    if not path.is_file():
        raise FileNotFoundError(f'checkpoint {path} does not exist')
    return path


def read_checkpoint(path: str | pathlib.Path) -> dict[str, Any]:
    """Load a checkpoint (a file or a run directory); ValueError if it is not a readable one of this version."""
    path = find_checkpoint(path)
    try:
        data = torch.load(path, map_location='cpu', weights_only=True)
    except Exception as err:  # torch raises several types for a truncated or foreign file
        raise ValueError(f'{path} is not a readable checkpoint: {err}') from err
    if not isinstance(data, dict) or data.get('format') != CHECKPOINT_FORMAT:
        raise ValueError(f'{path} is not a StylePong PPO checkpoint')
    if data.get('version') != CHECKPOINT_VERSION:
        raise ValueError(f'{path} has checkpoint version {data.get("version")}, this code reads {CHECKPOINT_VERSION}')
    return data


class EpisodeStatistics:
    """Per-iteration tallies: returns and lengths of ended episodes, the env's episode log averaged with
    its weights, and the means of the reward's parts."""

    def __init__(self, num_envs: int, device: torch.device, history: int = 200):
        self.current_return = torch.zeros(num_envs, device=device)
        self.current_length = torch.zeros(num_envs, device=device)
        self.returns: deque[float] = deque(maxlen=history)
        self.lengths: deque[float] = deque(maxlen=history)
        self.reset_iteration()

    def reset_iteration(self) -> None:
        self.episodes = 0
        self.log_sums: dict[str, float] = {}
        self.log_weights: dict[str, int] = {}
        self.reward_sums: dict[str, torch.Tensor | float] = {}
        self.steps = 0

    def record(
        self,
        rewards: torch.Tensor,
        dones: torch.Tensor,
        extras: dict[str, Any],
        reward_parts: dict[str, torch.Tensor] | None = None,
    ) -> None:
        self.current_return += rewards
        self.current_length += 1
        self.steps += 1
        if bool(dones.any()):
            done_idx = dones.nonzero(as_tuple=False).squeeze(-1)
            self.returns.extend(self.current_return[done_idx].tolist())
            self.lengths.extend(self.current_length[done_idx].tolist())
            self.current_return[done_idx] = 0.0
            self.current_length[done_idx] = 0.0
            self.episodes += int(done_idx.numel())
        weight = int(extras.get(env_contract.EXTRAS_LOG_WEIGHT, 0))
        if weight > 0:
            for key, value in extras[env_contract.EXTRAS_LOG].items():
                self.log_sums[key] = self.log_sums.get(key, 0.0) + float(value) * weight
                self.log_weights[key] = self.log_weights.get(key, 0) + weight
        for key, value in (reward_parts or {}).items():
            # Summed on the device and read once per iteration: a float() here would wait for the GPU
            # at every rollout step.
            self.reward_sums[key] = self.reward_sums.get(key, 0.0) + value.mean(dtype=torch.float64)

    def summary(self) -> dict[str, float]:
        out = {
            'mean_return': float(np.mean(self.returns)) if self.returns else math.nan,
            'mean_episode_length': float(np.mean(self.lengths)) if self.lengths else math.nan,
            'episodes': self.episodes,
        }
        for key, total in self.log_sums.items():
            out[key] = total / self.log_weights[key]
        for key, total in self.reward_sums.items():
            out[f'step_reward/{key}'] = float(total) / max(self.steps, 1)
        return out


class OnPolicyRunner:
    """Runs PPO (and the motion prior, for AMP) on a batched env: rollouts, updates, logs, checkpoints."""

    def __init__(
        self,
        env: env_contract.VecEnv,
        cfg: TrainConfig,
        run_dir: str | pathlib.Path,
        tensorboard: bool = True,
        motion_prior: MotionPrior | None = None,
    ):
        self.env = env
        self.cfg = cfg
        self.run_dir = pathlib.Path(run_dir)
        self.device = torch.device(env.device)
        self.tensorboard = tensorboard
        self.motion_prior = motion_prior
        amp = cfg.amp
        # amp.free_follow_through: a second value stream for the motion terms after the touch (MotionPrior.mix).
        self.free_follow_through = motion_prior is not None and amp is not None and amp.free_follow_through
        streams = 2 if self.free_follow_through else 1
        sizes = env_contract.StepSizes.of(env)
        self.actor_critic = ActorCritic.from_config(sizes, cfg.policy, value_streams=streams).to(self.device)
        self.alg = PPO(self.actor_critic, cfg.ppo)
        steps = cfg.ppo.num_steps_per_env
        self.storage = RolloutStorage(steps, env.num_envs, sizes, self.device, value_streams=streams)
        # Whether each environment's ball has touched the paddle before the coming step (free follow-through).
        self.touched = torch.zeros(env.num_envs, dtype=torch.bool, device=self.device)
        self.shuffle = torch.Generator()
        self.shuffle.manual_seed(cfg.runner.seed)
        self.iteration = 0
        self.env_steps = 0
        self.wall_time_s = 0.0  # summed over every session of this run
        self.sessions: list[dict[str, Any]] = []  # one entry per learn() call, over all sessions
        self.last_stats: dict[str, Any] = {}
        self.interrupted = False
        self.success_hold = (
            SuccessHold(
                cfg.runner.critic_warmup_iterations,
                amp.hold_success_margin,
                amp.hold_success_gain,
                amp.hold_success_smoothing,
            )
            if motion_prior is not None and amp is not None and amp.hold_success
            else None
        )

    # --- checkpoints -------------------------------------------------------------------------------
    @property
    def checkpoint_dir(self) -> pathlib.Path:
        return self.run_dir / CHECKPOINT_DIR

    def state_dict(self) -> dict[str, Any]:
        return {
            'format': CHECKPOINT_FORMAT,
            'version': CHECKPOINT_VERSION,
            'iteration': self.iteration,
            'env_steps': self.env_steps,
            'wall_time_s': self.wall_time_s,
            'architecture': self.actor_critic.architecture(),
            'model': self.actor_critic.state_dict(),
            'optimizer': self.alg.optimizer.state_dict(),
            'learning_rate': self.alg.learning_rate,
            'config': config_to_dict(self.cfg),
            'rng': capture_rng_state(self.shuffle),
            'sessions': [dict(s) for s in self.sessions],
            'motion_prior': self.motion_prior.state_dict() if self.motion_prior is not None else None,
            'success_hold': self.success_hold.state_dict() if self.success_hold is not None else None,
            'max_std': None if self.actor_critic.max_std is None else self.actor_critic.max_std.tolist(),
            'last_stats': {k: v for k, v in self.last_stats.items() if isinstance(v, (int, float))},
        }

    def save(self, path: str | pathlib.Path) -> pathlib.Path:
        """Write atomically: a run killed mid-save keeps its previous checkpoint intact."""
        path = pathlib.Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp = path.with_name(path.name + '.tmp')
        torch.save(self.state_dict(), tmp)
        os.replace(tmp, path)
        return path

    def load(self, path: str | pathlib.Path, restore_rng: bool = True) -> pathlib.Path:
        path = find_checkpoint(path)
        data = read_checkpoint(path)
        mine = self.actor_critic.architecture()
        if data['architecture'] != mine:
            diff = {k: (data['architecture'].get(k), v) for k, v in mine.items() if data['architecture'].get(k) != v}
            raise ValueError(f'checkpoint {path} does not fit this network/env (checkpoint vs now): {diff}')
        self.actor_critic.load_state_dict(data['model'])
        # A slim checkpoint (the model and its records only, as numbered checkpoints are kept to save
        # space) continues with a fresh optimiser and, under AMP, a fresh discriminator.
        if data.get('optimizer') is not None:
            self.alg.optimizer.load_state_dict(data['optimizer'])
        self.alg._set_learning_rate(data['learning_rate'])
        self.iteration = int(data['iteration'])
        self.env_steps = int(data['env_steps'])
        self.wall_time_s = float(data['wall_time_s'])
        self.last_stats = dict(data.get('last_stats') or {})
        self.sessions = [dict(s) for s in data.get('sessions') or []]
        if self.motion_prior is not None and data.get('motion_prior') is not None:
            self.motion_prior.load_state_dict(data['motion_prior'])
        if self.success_hold is not None and data.get('success_hold') is not None:
            self.success_hold.load_state_dict(data['success_hold'])
            self.motion_prior.motion_scale = self.success_hold.scale
        if data.get('max_std') is not None:
            self.actor_critic.max_std = torch.tensor(data['max_std'], device=self.device)
        if restore_rng and data.get('rng') is not None:
            restore_rng_state(data['rng'], self.shuffle)
        return path

    def start_from(self, path: str | pathlib.Path) -> pathlib.Path:
        """Begin this run from another run's network (actor, critic, normalisers, action noise): a skill to
        build on. Everything else starts afresh: iteration 0, the optimiser, the discriminator. A critic of
        another number of value streams is fitted to this run's (rl.networks.fit_value_streams)."""
        path = find_checkpoint(path)
        data = read_checkpoint(path)
        theirs = data['architecture']
        if network_sizes(theirs) != network_sizes(self.actor_critic.architecture()):
            raise ValueError(f'checkpoint {path} holds a network of another shape: {theirs}')
        self.actor_critic.load_state_dict(fit_value_streams(data['model'], theirs, self.actor_critic.value_streams))
        if self.cfg.policy.keep_skill_std:
            self.actor_critic.max_std = self.actor_critic.action_std().detach().clone()
        return path

    def _save_checkpoints(self) -> None:
        self.save(self.checkpoint_dir / LAST_CHECKPOINT)
        if self.iteration % self.cfg.runner.save_interval == 0:
            self.save(self.checkpoint_dir / f'model_{self.iteration:06d}.pt')
            keep = self.cfg.runner.keep_checkpoints
            if keep > 0:
                for old in sorted(self.checkpoint_dir.glob('model_*.pt'))[:-keep]:
                    old.unlink()

    # --- training ----------------------------------------------------------------------------------
    def _sync(self) -> None:
        # CUDA kernels run asynchronously: without a sync the world/learn split of the timings is wrong.
        if self.device.type == 'cuda':
            torch.cuda.synchronize(self.device)

    def _collect(self, obs: torch.Tensor, critic_obs: torch.Tensor, stats: EpisodeStatistics):
        """One rollout of num_steps_per_env steps into the storage; returns the next obs and timings."""
        gamma = self.cfg.ppo.gamma
        world_s = policy_s = style_s = 0.0
        self.storage.clear()
        with torch.inference_mode():
            for _ in range(self.storage.num_steps):
                t0 = time.perf_counter()
                step = self.alg.act(obs, critic_obs)
                self._sync()
                t1 = time.perf_counter()
                obs, critic_obs, rewards, dones, extras = self.env.step(step.actions)
                self._sync()
                t2 = time.perf_counter()
                rewards = rewards.to(torch.float32)
                if not (
                    torch.isfinite(obs).all() and torch.isfinite(critic_obs).all() and torch.isfinite(rewards).all()
                ):
                    raise FloatingPointError(
                        'the env returned non-finite observations or rewards; '
                        'stopping before they poison the normalisers'
                    )
                parts = None
                if self.motion_prior is not None:
                    frames = extras[env_contract.EXTRAS_STYLE_STATE]
                    labels = extras.get(env_contract.EXTRAS_STYLE_LABEL)
                    style = self.motion_prior.observe(
                        frames, dones, self.env.style_state(), labels, extras.get(env_contract.EXTRAS_STYLE_PHASE)
                    )
                    pose = self.motion_prior.pose_reward(frames, extras.get(env_contract.EXTRAS_STYLE_TIME), labels)
                    stroke = self.motion_prior.stroke_reward(
                        frames, extras.get(env_contract.EXTRAS_STYLE_STROKE_END), dones, self.env.style_state(), labels
                    )
                    parts = {'task': rewards, 'style': style, 'pose': pose, 'stroke': stroke}
                    after_touch, stream_dones = self._follow_through(extras, dones)
                    rewards = self.motion_prior.mix(
                        rewards, style, extras.get(env_contract.EXTRAS_STYLE_WEIGHT), pose, stroke, after_touch
                    )
                    self._sync()
                    style_s += time.perf_counter() - t2
                else:
                    stream_dones = dones
                stats.record(rewards if rewards.dim() == 1 else rewards.sum(-1), dones, extras, parts)
                # A time-limit end is not a real terminal: bootstrap with the value of the state it was cut at.
                time_outs = extras.get(env_contract.EXTRAS_TIME_OUTS)
                if time_outs is not None:
                    time_outs = time_outs.to(torch.float32)
                    rewards = rewards + gamma * step.values * (time_outs if rewards.dim() == 1 else time_outs[:, None])
                self.storage.add(
                    step.norm_obs,
                    step.norm_critic_obs,
                    step.actions,
                    rewards,
                    stream_dones.to(torch.float32),
                    step.values,
                    step.log_probs,
                    step.mean,
                    step.std,
                )
                world_s += t2 - t1
                policy_s += t1 - t0
            last_values = self.alg.value(critic_obs)
            self.storage.compute_returns(last_values, gamma, self.cfg.ppo.lam, self.cfg.ppo.normalize_advantages)
        return obs, critic_obs, world_s, policy_s, style_s

    def _follow_through(self, extras: dict[str, Any], dones: torch.Tensor) -> tuple[torch.Tensor | None, torch.Tensor]:
        """With a free follow-through: which steps began after the paddle's touch [N], and each value stream's
        ends [N, 2] (the episode's, and for the follow-through's stream also the touch: the step that touches
        does not bootstrap from it). Without: (None, dones)."""
        if not self.free_follow_through:
            return None, dones
        phase = extras.get(env_contract.EXTRAS_STYLE_PHASE)
        if phase is None:
            raise ValueError("amp.free_follow_through: the env must give each step's 'style_phase'")
        touched_now = phase.to(torch.bool)
        after_touch = self.touched
        touches = touched_now & ~after_touch
        self.touched = touched_now & ~dones
        return after_touch, torch.stack((dones, dones | touches), dim=-1)

    def learn(
        self,
        until_iteration: int,
        progress_bar: bool | None = None,
        session_info: dict[str, Any] | None = None,
        until_wall_time_s: float | None = None,
        on_iteration: Callable[[dict[str, Any]], None] | None = None,
    ) -> dict[str, Any]:
        """Train until the run has `until_iteration` iterations, or (until_wall_time_s) until its training
        time summed over all its sessions reaches that budget; Ctrl-C stops after saving a checkpoint.
        session_info (e.g. the command line) is kept with this session's record in checkpoints;
        on_iteration is called with each iteration's statistics once its checkpoint is saved."""

        def budget_left() -> bool:
            return until_wall_time_s is None or self.wall_time_s < until_wall_time_s

        progress_bar = self.cfg.runner.progress_bar if progress_bar is None else progress_bar
        start = self.iteration
        log = TrainingLog(self.run_dir, start, tensorboard=self.tensorboard)
        stats = EpisodeStatistics(self.env.num_envs, self.device)
        bar = None
        if progress_bar and until_iteration > start:
            from tqdm import tqdm

            tty = sys.stderr.isatty()
            bar = tqdm(
                total=until_iteration,
                initial=start,
                unit='it',
                dynamic_ncols=True,
                mininterval=0.5 if tty else 30.0,
                desc='PPO' if self.motion_prior is None else 'AMP',
            )
        self.actor_critic.train()
        batch = self.storage.num_steps * self.env.num_envs
        session = {
            'start_iteration': start,
            'end_iteration': start,
            'wall_time_s': 0.0,
            'num_envs': self.env.num_envs,
            'device': describe_device(self.device),
            **(session_info or {}),
        }
        self.sessions.append(session)
        try:
            with torch.inference_mode():
                obs, critic_obs = self.env.reset()
                self.touched.zero_()
                if self.motion_prior is not None:
                    self.motion_prior.start(self.env.style_state())
            while self.iteration < until_iteration and budget_left():
                t_start = time.perf_counter()
                self.alg.apply_schedule(self.iteration, until_iteration)
                stats.reset_iteration()
                obs, critic_obs, world_s, policy_s, style_s = self._collect(obs, critic_obs, stats)
                t_learn = time.perf_counter()
                losses = self.alg.update(
                    self.storage, self.shuffle, update_actor=self.iteration >= self.cfg.runner.critic_warmup_iterations
                )
                self._sync()
                t_disc = time.perf_counter()
                if self.motion_prior is not None:
                    losses.update(self.motion_prior.update())
                    self._sync()
                t_end = time.perf_counter()
                # The discriminator's share of an iteration: scoring windows in the rollout plus its updates.
                style_s += t_end - t_disc
                self.iteration += 1
                self.env_steps += batch
                iteration_s = t_end - t_start
                self.wall_time_s += iteration_s
                session['end_iteration'] = self.iteration
                session['wall_time_s'] += iteration_s
                self.last_stats = {
                    'iteration': self.iteration,
                    'env_steps': self.env_steps,
                    'wall_time_s': self.wall_time_s,
                    'iteration_time_s': iteration_s,
                    'samples_per_s': batch / iteration_s,
                    'world_s': world_s,
                    'policy_s': policy_s,
                    'learn_s': t_disc - t_learn,
                    'style_s': style_s,
                    'world_share': world_s / iteration_s,
                    'style_share': style_s / iteration_s,
                    **stats.summary(),
                    **losses,
                }
                if self.success_hold is not None:
                    self.motion_prior.motion_scale = self.success_hold.observe(
                        self.last_stats.get('success_rate'), self.last_stats.get('episodes')
                    )
                    self.last_stats['motion_scale'] = self.motion_prior.motion_scale
                log.write(self.last_stats)
                self._save_checkpoints()
                if on_iteration is not None:
                    on_iteration(self.last_stats)
                if bar is not None:
                    bar.update(1)
                    bar.set_postfix(
                        success=_fmt(self.last_stats.get('success_rate', math.nan)),
                        ret=_fmt(self.last_stats['mean_return']),
                        sps=f'{self.last_stats["samples_per_s"]:.0f}',
                        refresh=False,
                    )
        except KeyboardInterrupt:
            # The checkpoint of the last completed iteration is already on disk; keep it and stop.
            self.interrupted = True
        finally:
            if session['end_iteration'] == start:
                self.sessions.remove(session)
            if bar is not None:
                bar.close()
            log.close()
        return self.last_stats


def _fmt(value: float) -> str:
    return 'n/a' if value is None or (isinstance(value, float) and math.isnan(value)) else f'{value:.3f}'
