"""The one training configuration: explicit hyper-parameters in dataclasses, loaded from and saved to YAML.

A YAML file has the sections `policy`, `ppo`, `runner`, `task` and, for the motion prior, `amp`.
All but `task` map onto the dataclasses below; unknown keys are errors (a typo must not silently fall
back to a default). `task` is kept as a plain dict and handed to the task module's own
`TaskConfig(**task)`, which owns and validates those fields. No `amp` section: PPO alone.

The defaults of `policy`, `ppo` and `runner` (and TaskConfig's num_envs) are the values of the shipped
config/ppo.yaml, the source: what a section leaves out is what the baseline ran with, and
test_ppo.py's test_defaults_are_the_shipped_ppo_yaml keeps the two equal.

A file may start from another: `extends: base.yaml` (relative to the file) takes the base's sections
and lets the file change keys in them, so an experiment states only how it differs from its recipe.
What a run saves is the resolved configuration, whole.
"""

from __future__ import annotations

import copy
import dataclasses
import pathlib
from dataclasses import dataclass, field
from typing import Any

import yaml

from stylepong_common.settings import check_ranges, non_negative, positive, within

SCHEDULES = ('adaptive', 'fixed', 'linear')


@dataclass
class PolicyConfig:
    """The actor-critic networks: hidden layers, activation, initial and minimum std, normalisation."""

    actor_hidden_dims: list[int] = field(default_factory=lambda: [256, 128, 64])
    critic_hidden_dims: list[int] = field(default_factory=lambda: [256, 128, 64])
    activation: str = 'elu'
    init_noise_std: float = positive(0.5)  # initial std of the Gaussian policy, in action units
    min_std: float = 1e-3  # floor on the std (keeps log-probs finite)
    # From a skill (--from), its std is the ceiling: the entropy bonus otherwise widens the noise once the
    # task is learnt, and training returns fall with it while the deterministic actor's do not.
    keep_skill_std: bool = False
    normalize_observations: bool = True  # running mean/var normalisation of actor and critic inputs


@dataclass
class PPOConfig:
    """PPO's hyperparameters: rollout length, epochs, minibatches, losses and learning-rate schedule."""

    num_steps_per_env: int = positive(24)  # rollout length T per iteration; batch = T x num_envs samples
    num_learning_epochs: int = positive(5)
    num_mini_batches: int = positive(4)
    clip_param: float = positive(0.2)  # PPO ratio clip epsilon
    gamma: float = within(0.99, 0.0, 1.0)  # discount per policy step (60 Hz)
    lam: float = within(0.95, 0.0, 1.0)  # GAE lambda
    value_loss_coef: float = 1.0
    use_clipped_value_loss: bool = True
    entropy_coef: float = 0.002
    learning_rate: float = positive(1e-3)
    schedule: str = 'adaptive'  # adaptive (from the KL), fixed, or linear decay to min_learning_rate
    desired_kl: float = positive(0.01)  # target KL for the adaptive schedule
    min_learning_rate: float = 1e-5
    max_learning_rate: float = 1e-2
    max_grad_norm: float = positive(1.0)
    normalize_advantages: bool = True


@dataclass
class RunnerConfig:
    """The run: iterations, seed, device, threads and checkpointing."""

    iterations: int = non_negative(1300)  # total iterations of the run (a resumed run continues to this)
    seed: int = non_negative(1)  # below world_spec.FIRST_EVALUATION_SEED
    device: str = 'cpu'  # 'cpu' or 'cuda' (or 'cuda:N')
    num_threads: int = positive(2)  # torch intra-op threads on CPU
    save_interval: int = positive(50)  # iterations between numbered checkpoints (last.pt is every iteration)
    keep_checkpoints: int = non_negative(0)  # numbered checkpoints kept besides last.pt (0 keeps all)
    # The run's first iterations step the critic alone: a run started from another run's network (a skill)
    # meets rewards its critic never valued, and its first advantages would be noise that undoes the skill.
    critic_warmup_iterations: int = non_negative(0)
    progress_bar: bool = True


# What of each arm state the discriminator may see (stylepong_policy.rl.amp.feature_columns).
FRAME_FEATURES = ('q_qdot', 'q')


@dataclass
class AMPConfig:
    """The adversarial motion prior (stylepong_policy.rl.amp); config/amp.yaml says why each value."""

    dataset: str = ''  # reference-motion .npz of build_dataset ('' : built from ros2_ws/bags)
    speed_factors: list[int] | None = None  # clips used (None: all; [1]: the originals only, "amp-noaug")
    sequence_length: int = positive(4)  # L arm states per discriminator window, at the policy rate
    frame_features: str = 'q_qdot'  # of each arm state: 'q_qdot' (positions and velocities) or 'q'
    hidden_dims: list[int] = field(default_factory=lambda: [512, 256])
    activation: str = 'elu'
    normalizer_clip: float = positive(5.0)
    learning_rate: float = positive(1e-4)
    weight_decay_trunk: float = non_negative(1e-4)
    weight_decay_head: float = non_negative(1e-2)
    # The weight of E_ref |grad D|^2, and the discriminator's minibatch steps per PPO update.
    grad_penalty: float = non_negative(5.0)
    updates_per_iteration: int = non_negative(8)
    batch_size: int = positive(4096)  # reference and policy windows per discriminator step (each)
    replay_size: int = positive(200000)  # policy windows kept for the discriminator's negatives
    style_reward: str = 'lsgan'  # 'lsgan' (AMP's) or 'log' (the paper's -log, bounded)
    condition_on_label: bool = False  # D also sees each window's label (the clip's; the env's 'style_label')
    condition_on_phase: bool = False  # D also sees if a window ends before or after the hit ('style_phase')
    w_task: float = non_negative(1.0)
    w_style: float = non_negative(0.05)
    # The pose prior (rl.pose_prior): w_pose exp(-|q - nearest demonstrated pose of the label| / sigma) per step.
    w_pose: float = non_negative(0.0)
    pose_sigma_rad: float = positive(0.3)
    # After the touch, each clip's follow-through to its end over the stroke's remaining time (the env's
    # 'style_follow_through_s'), where DTW pairs the stroke's end; false: on the clips' own clock.
    pose_follows_through: bool = False
    # The stroke prior (rl.stroke_prior): w_stroke exp(-DTW(stroke, nearest clip) / (sigma frames)), once a stroke.
    w_stroke: float = non_negative(0.0)
    stroke_sigma_rad: float = positive(0.4)
    # Held style (rl.success_hold): the motion terms scaled down while training success is below the skill's
    # own (its warm-up iterations') less hold_success_margin, and back up as it recovers.
    hold_success: bool = False
    hold_success_margin: float = non_negative(0.03)
    hold_success_gain: float = positive(0.15)
    hold_success_smoothing: float = within(0.1, 0.01, 1.0)
    # A free follow-through: the per-step motion terms after the paddle's touch ('style_phase') are not held,
    # and a value stream of their own keeps them from flowing back to the steps before the touch.
    free_follow_through: bool = False

    def validate(self) -> None:
        check_ranges(self, prefix='amp.')
        if self.frame_features not in FRAME_FEATURES:
            raise ValueError(f'amp.frame_features must be one of {FRAME_FEATURES}, got {self.frame_features!r}')
        if self.style_reward not in ('lsgan', 'log'):
            raise ValueError(f"amp.style_reward must be 'lsgan' or 'log', got {self.style_reward!r}")
        for name in (
            'condition_on_label',
            'condition_on_phase',
            'hold_success',
            'free_follow_through',
            'pose_follows_through',
        ):
            if not isinstance(getattr(self, name), bool):
                raise ValueError(f'amp.{name} must be true or false, got {getattr(self, name)!r}')
        if self.speed_factors is not None and (not self.speed_factors or min(self.speed_factors) < 1):
            raise ValueError(f'amp.speed_factors must be null or a list of factors >= 1, got {self.speed_factors}')


@dataclass
class TrainConfig:
    """A whole training configuration: policy, PPO, runner, task and (for AMP) the motion prior."""

    policy: PolicyConfig = field(default_factory=PolicyConfig)
    ppo: PPOConfig = field(default_factory=PPOConfig)
    runner: RunnerConfig = field(default_factory=RunnerConfig)
    task: dict[str, Any] = field(default_factory=dict)
    amp: AMPConfig | None = None  # None: PPO on the task reward alone

    def validate(self) -> 'TrainConfig':
        if self.ppo.schedule not in SCHEDULES:
            raise ValueError(f'ppo.schedule must be one of {SCHEDULES}, got {self.ppo.schedule!r}')
        check_ranges(self.policy, prefix='policy.')
        check_ranges(self.ppo, prefix='ppo.')
        check_ranges(self.runner, prefix='runner.')
        if not isinstance(self.task, dict):
            raise ValueError(f'task must be a mapping of TaskConfig fields, got {type(self.task).__name__}')
        if self.amp is not None:
            self.amp.validate()
        return self


METHODS = ('ppo', 'amp', 'amp-noaug')
ORIGINAL_CLIPS_ONLY = [1]  # amp-noaug's speed factors: the demonstrations as recorded, no speed-ups


def method_of(cfg: 'TrainConfig') -> str:
    """ppo (no motion prior), amp (all clips) or amp-noaug (the original clips only)."""
    if cfg.amp is None:
        return 'ppo'
    return 'amp-noaug' if cfg.amp.speed_factors == ORIGINAL_CLIPS_ONLY else 'amp'


_SECTIONS = {'policy': PolicyConfig, 'ppo': PPOConfig, 'runner': RunnerConfig}
_OPTIONAL_SECTIONS = {'amp': AMPConfig}


def config_from_dict(data: dict[str, Any] | None) -> TrainConfig:
    """A validated TrainConfig from a mapping; ValueError for unknown sections or keys."""
    data = dict(data or {})
    known = set(_SECTIONS) | set(_OPTIONAL_SECTIONS) | {'task'}
    unknown = set(data) - known
    if unknown:
        raise ValueError(f'unknown config sections {sorted(unknown)}; expected {sorted(known)}')
    sections = {}
    for name, cls in {**_SECTIONS, **_OPTIONAL_SECTIONS}.items():
        if name in _OPTIONAL_SECTIONS and data.get(name) is None:
            continue
        values = data.get(name) or {}
        if not isinstance(values, dict):
            raise ValueError(f'config section {name!r} must be a mapping')
        allowed = {f.name for f in dataclasses.fields(cls)}
        bad = set(values) - allowed
        if bad:
            raise ValueError(f'unknown keys in section {name!r}: {sorted(bad)}; allowed: {sorted(allowed)}')
        sections[name] = cls(**values)
    return TrainConfig(**sections, task=copy.deepcopy(data.get('task') or {})).validate()


def config_to_dict(cfg: TrainConfig) -> dict[str, Any]:
    """The configuration as plain dicts (what save_config writes)."""
    return dataclasses.asdict(cfg)


EXTENDS_KEY = 'extends'


def _read_mapping(path: pathlib.Path) -> dict[str, Any]:
    # Each try holds the one call whose error it names: reading fails with OSError, parsing with YAMLError.
    try:
        text = path.read_text()
    except OSError as err:
        raise ValueError(f'cannot read config {path}: {err}') from err
    try:
        data = yaml.safe_load(text)
    except yaml.YAMLError as err:
        raise ValueError(f'config {path} is not valid YAML: {err}') from err
    if data is not None and not isinstance(data, dict):
        raise ValueError(f'config {path} must be a YAML mapping')
    return data or {}


def merged_sections(base: dict[str, Any], changes: dict[str, Any]) -> dict[str, Any]:
    """`base` with each section of `changes` laid over it key by key (a non-mapping value replaces)."""
    result = copy.deepcopy(base)
    for name, values in changes.items():
        if isinstance(values, dict) and isinstance(result.get(name), dict):
            result[name] = {**result[name], **copy.deepcopy(values)}
        else:
            result[name] = copy.deepcopy(values)
    return result


def _resolved_mapping(path: pathlib.Path, chain: tuple[pathlib.Path, ...] = ()) -> dict[str, Any]:
    """The file's sections with those of the files it extends beneath them."""
    if path.resolve() in chain:
        raise ValueError(f'config {path} extends itself through {[str(p) for p in chain]}')
    data = _read_mapping(path)
    base_name = data.pop(EXTENDS_KEY, None)
    if base_name is None:
        return data
    if not isinstance(base_name, str):
        raise ValueError(f'config {path}: {EXTENDS_KEY} must be a file name, got {base_name!r}')
    return merged_sections(_resolved_mapping(path.parent / base_name, chain + (path.resolve(),)), data)


def load_config(path: str | pathlib.Path) -> TrainConfig:
    """Read a YAML configuration (and what it extends); ValueError naming the file for anything wrong."""
    path = pathlib.Path(path)
    data = _resolved_mapping(path)
    try:
        return config_from_dict(data)
    except (TypeError, ValueError) as err:
        raise ValueError(f'config {path}: {err}') from err


def save_config(cfg: TrainConfig, path: str | pathlib.Path) -> None:
    """Write the configuration as YAML."""
    pathlib.Path(path).write_text(yaml.safe_dump(config_to_dict(cfg), sort_keys=False))
