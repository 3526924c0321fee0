"""The adversarial motion prior: a discriminator on sequences of L arm states, and the style reward it gives.

The method of "Stylized Table Tennis Robots Skill Learning with Incomplete Human Demonstrations" (after
Peng et al.'s AMP): a discriminator D learns to tell windows of L consecutive arm states (q, qdot at the
policy rate) of the demonstrations from those of the policy, with the least-squares GAN loss

    E_ref[(D - 1)^2] + E_policy[(D + 1)^2] + w_gp E_ref[|grad D|^2]

and weight decay; the policy is rewarded for windows D takes for demonstrations,
r = w_task r_task + w_style r_style. Windows longer than a transition (L > 2) matter here: a slow,
dragged demonstration changes little from one frame to the next, and a two-frame discriminator barely
sees the motion's shape.

Nothing here knows the task: the runner hands over the env's per-step style frames (rl.env contract).

Labelled motions (`amp.condition_on_label`): demonstrations of several kinds of motion (the clips'
labels) teach one unconditioned D what any of them looks like, so a policy may answer every situation with
the kind easiest for it and still look like a demonstration. Conditioned, D also sees the label (one-hot)
of the kind each window should be: a reference window its clip's label, a policy window the label the env
asks for at that step (rl.env's 'style_label', in the order of its `style_labels`). D then learns each
kind of motion apart, and a window earns the style reward only as the kind its situation asks for.

Phases (`amp.condition_on_phase`): a stroke is a swing to the ball and a follow-through after it, and an
unconditioned D judges a window after the hit against every demonstrated window, home and back-swing
included, so an arm that returns home or waits after its hit looks as demonstrated as one that follows
through. Conditioned on the phase, D also sees whether a window's last frame (the frame its reward is for)
lies before or after the hit: a reference window from its clip (`dataset.hit_frame`, the fastest frame of
the last swing), a policy window from the env (rl.env's 'style_phase': the paddle has touched the ball).
With labels too, the condition is the pair (label, phase), one one-hot of labels x 2.

The pieces:
  ReferenceMotion   windows of the demonstrations, uniform over all windows inside one clip
  StyleHistory      each environment's last L frames, restarted at its episode's first frame
  ReplayBuffer      recent policy windows, for the discriminator's negatives
  Discriminator     one running normaliser of its inputs, then an MLP trunk and a linear head
  style_reward      the reward for a discriminator output
  MotionPrior       owns them all, trains D and scores the policy's windows
"""

from __future__ import annotations

import math
from typing import Any, Sequence

import numpy as np
import torch
from torch import nn

from stylepong_policy.training.dataset import window_start_indices

from .config import FRAME_FEATURES, AMPConfig
from .networks import make_mlp
from .normalizer import RunningNormalizer
from .pose_prior import PosePrior
from .stroke_prior import StrokePrior

STYLE_REWARDS = ('lsgan', 'log')
# A conditioned stroke's phases: before the hit (0) and after it (1).
PHASES = 2
# The discriminator's first linear layer (trunk[0]) in its state dict: the one the conditions enter.
FIRST_LAYER_WEIGHT = 'trunk.0.weight'
# The bounded -log form: a discriminator "probability" of 1 - 1e-4 or more earns the full reward.
LOG_REWARD_FLOOR = 1e-4


def feature_columns(features: str, frame_size: int) -> slice:
    """The columns of a frame of `frame_size` values that `features` keeps. A style frame is the joint
    positions followed by as many joint velocities (the env contract's style_state, the dataset's states())."""
    if features == 'q_qdot':
        return slice(0, frame_size)
    if features == 'q':
        if frame_size % 2:
            raise ValueError(f'a frame of {frame_size} values is not positions and velocities')
        return slice(0, frame_size // 2)
    raise ValueError(f'unknown frame features {features!r}; choose one of {FRAME_FEATURES}')


class ReferenceMotion:
    """Every window of `length` consecutive frames lying inside one clip, drawn uniformly.

    frames [F, D] (all clips concatenated, in order), clip_starts / clip_lengths [C], and optionally clip_labels [C]
    (label indices) with the names they index and frame_after_hit [F] (bool per frame). The window start
    indices, each window's label and its phase (1 when its last frame is after the hit) are built once; a
    draw is one random index per window and a gather.
    """

    def __init__(
        self,
        frames: np.ndarray | torch.Tensor,
        clip_starts: Sequence[int],
        clip_lengths: Sequence[int],
        length: int,
        device: torch.device | str = 'cpu',
        clip_labels: Sequence[int] | None = None,
        label_names: Sequence[str] = (),
        frame_after_hit: np.ndarray | None = None,
    ):
        self.device = torch.device(device)
        self.frames = torch.as_tensor(np.asarray(frames), dtype=torch.float32, device=self.device)
        starts = window_start_indices(clip_starts, clip_lengths, length)
        if not len(starts):
            raise ValueError(f'no reference clip has {length} frames')
        self.starts = torch.as_tensor(starts, dtype=torch.long, device=self.device)
        self.offsets = torch.arange(length, device=self.device)
        self.length = int(length)
        self.label_names = tuple(label_names)
        # Each window's label is its clip's: the clip whose start is the last one at or before the window's.
        per_clip = np.zeros(len(clip_starts), dtype=np.int64) if clip_labels is None else np.asarray(clip_labels)
        clip_of_window = np.searchsorted(np.asarray(clip_starts), starts, side='right') - 1
        self.labels = torch.as_tensor(per_clip[clip_of_window], dtype=torch.long, device=self.device)
        after = np.zeros(len(self.frames), dtype=bool) if frame_after_hit is None else np.asarray(frame_after_hit)
        if after.shape != (len(self.frames),):
            raise ValueError(f'frame_after_hit needs one flag per frame ({len(self.frames)}), got shape {after.shape}')
        self.phases = torch.as_tensor(after[starts + length - 1], dtype=torch.long, device=self.device)

    @classmethod
    def from_dataset(
        cls,
        dataset,
        length: int,
        speed_factors: Sequence[int] | None = None,
        device: torch.device | str = 'cpu',
        features: str = 'q_qdot',
        label_names: Sequence[str] = (),
        phases: bool = False,
    ) -> 'ReferenceMotion':
        """Windows of a stylepong_policy.training.dataset.ReferenceDataset's (q, qdot) frames, or of their `features`,
        of the clips with these speed factors (None: all, originals and speed-ups). With label_names, each
        window also carries the index of its clip's label among them (a clip with another label: an error);
        with phases, whether its last frame is at or after its clip's hit."""
        clips = dataset.select(speed_factors=speed_factors)
        if not len(clips):
            raise ValueError(f'the dataset has no clip with speed factor in {list(speed_factors or [])}')
        states = dataset.states()
        frames = states[:, feature_columns(features, states.shape[1])]
        clip_labels = None
        if label_names:
            unknown = sorted({str(dataset.label[c]) for c in clips} - set(label_names))
            if unknown:
                raise ValueError(
                    f'the dataset has clips labelled {unknown}, which the env does not ask for '
                    f'(it asks for {list(label_names)})'
                )
            clip_labels = [list(label_names).index(str(dataset.label[c])) for c in clips]
        return cls(
            frames,
            dataset.clip_start[clips],
            dataset.clip_length[clips],
            length,
            device,
            clip_labels,
            label_names,
            dataset.after_hit() if phases else None,
        )

    @property
    def num_windows(self) -> int:
        return int(self.starts.numel())

    def windows(self, indices: torch.Tensor) -> torch.Tensor:
        """Windows [B, L, D] starting at self.starts[indices]."""
        return self.frames[self.starts[indices][:, None] + self.offsets[None, :]]

    def draw(self, count: int, generator: torch.Generator | None = None) -> torch.Tensor:
        """Indices of `count` windows drawn uniformly (for windows() and labels)."""
        return torch.randint(self.num_windows, (count,), generator=generator, device=self.device)

    def sample(self, count: int, generator: torch.Generator | None = None) -> torch.Tensor:
        return self.windows(self.draw(count, generator))


class StyleHistory:
    """The last L style frames of each environment [N, L, D], oldest first.

    A new episode's history is its first frame repeated: a window never mixes two episodes.
    """

    def __init__(self, first_frames: torch.Tensor, length: int):
        self.frames = first_frames[:, None, :].repeat(1, length, 1)

    def push(self, frames: torch.Tensor) -> torch.Tensor:
        """Append this step's frames [N, D]; returns the windows ending with them."""
        self.frames = torch.cat((self.frames[:, 1:], frames[:, None, :]), dim=1)
        return self.frames

    def restart(self, env_ids: torch.Tensor, first_frames: torch.Tensor) -> None:
        self.frames[env_ids] = first_frames[:, None, :]


class ReplayBuffer:
    """The last `capacity` policy windows and their conditions (first in, first out); uniform draws among
    those held."""

    def __init__(self, capacity: int, window_shape: tuple[int, int], device: torch.device | str):
        self.data = torch.zeros((int(capacity), *window_shape), device=device)
        self.conditions = torch.zeros(int(capacity), dtype=torch.long, device=device)
        self.size = 0
        self.next = 0

    def insert(self, windows: torch.Tensor, conditions: torch.Tensor | None = None) -> None:
        """Store windows [B, L, D] with their condition indices [B] (None: 0, an unconditioned prior's)."""
        capacity = self.data.shape[0]
        windows = windows[-capacity:]
        count = windows.shape[0]
        index = (self.next + torch.arange(count, device=self.data.device)) % capacity
        self.data[index] = windows
        self.conditions[index] = 0 if conditions is None else conditions[-capacity:]
        self.next = (self.next + count) % capacity
        self.size = min(self.size + count, capacity)

    def draw(self, count: int, generator: torch.Generator | None = None) -> torch.Tensor:
        """Indices of `count` stored windows drawn uniformly (for data and conditions)."""
        if self.size == 0:
            raise RuntimeError('the replay buffer is empty')
        return torch.randint(self.size, (count,), generator=generator, device=self.data.device)

    def sample(self, count: int, generator: torch.Generator | None = None) -> torch.Tensor:
        return self.data[self.draw(count, generator)]


class Discriminator(nn.Module):
    """D(window[, condition]): normalise each frame with one running mean/std, flatten, append the
    condition's one-hot when there are conditions (num_conditions of them: labels, or labels x phases),
    MLP trunk, linear head."""

    def __init__(
        self,
        frame_size: int,
        length: int,
        hidden_dims: Sequence[int],
        activation: str = 'elu',
        normalizer_clip: float = 5.0,
        num_conditions: int = 0,
    ):
        super().__init__()
        self.frame_size, self.length, self.num_conditions = int(frame_size), int(length), int(num_conditions)
        self.normalizer = RunningNormalizer(self.frame_size, clip=normalizer_clip)
        mlp = make_mlp(self.frame_size * self.length + self.num_conditions, hidden_dims, 1, activation)
        self.trunk = mlp[:-1]
        self.head = mlp[-1]

    def normalize(self, windows: torch.Tensor) -> torch.Tensor:
        """Normalised windows [B, L * D]: the input of both the loss and the gradient penalty."""
        return self.normalizer(windows).flatten(1)

    def forward(self, normalized: torch.Tensor, conditions: torch.Tensor | None = None) -> torch.Tensor:
        if self.num_conditions:
            if conditions is None:
                raise ValueError('this discriminator is conditioned: give each window its condition index')
            one_hot = nn.functional.one_hot(conditions, self.num_conditions).to(normalized)
            normalized = torch.cat((normalized, one_hot), dim=1)
        return self.head(self.trunk(normalized)).squeeze(-1)

    def score(self, windows: torch.Tensor, conditions: torch.Tensor | None = None) -> torch.Tensor:
        """D of raw windows [B, L, D] (with their condition indices [B] when conditioned) -> [B]."""
        return self(self.normalize(windows), conditions)


def style_reward(d: torch.Tensor, kind: str = 'lsgan') -> torch.Tensor:
    """The style reward in [0, 1] for discriminator outputs d (LSGAN targets: +1 reference, -1 policy).

    'lsgan'  AMP's max(0, 1 - (d - 1)^2 / 4): 1 at the reference target, 0 at the policy target and
             beyond; bounded and smooth, the form AMP found stable with a least-squares discriminator.
    'log'    the paper's -log form, made bounded: with p = clamp((d + 1) / 2, 0, 1) the discriminator's
             belief that the window is a demonstration, -log(max(1 - p, 1e-4)) / -log(1e-4). The paper's
             -log D is unbounded (and undefined for d <= 0) on an LSGAN output, so this maps d to [0, 1]
             first and caps the log, as the logistic AMP implementations do.
    """
    if kind == 'lsgan':
        return (1.0 - 0.25 * (d - 1.0).square()).clamp_min(0.0)
    if kind == 'log':
        p = ((d + 1.0) * 0.5).clamp(0.0, 1.0)
        return -torch.log((1.0 - p).clamp_min(LOG_REWARD_FLOOR)) / -math.log(LOG_REWARD_FLOOR)
    raise ValueError(f'unknown style reward {kind!r}; choose one of {STYLE_REWARDS}')


def _adam_with_decay(disc: Discriminator, cfg: AMPConfig) -> torch.optim.Adam:
    """One optimiser, two weight decays: light on the trunk, heavy on the head (a head with large weights
    is how a least-squares discriminator overfits and saturates)."""
    return torch.optim.Adam(
        [
            {'params': list(disc.trunk.parameters()), 'weight_decay': cfg.weight_decay_trunk},
            {'params': list(disc.head.parameters()), 'weight_decay': cfg.weight_decay_head},
        ],
        lr=cfg.learning_rate,
    )


class MotionPrior:
    """The discriminator, its data and its training, and the style reward for the policy's windows."""

    def __init__(
        self,
        cfg: AMPConfig,
        reference: ReferenceMotion,
        frame_size: int,
        num_envs: int,
        device: torch.device | str,
        seed: int = 0,
        pose_prior: PosePrior | None = None,
        stroke_prior: StrokePrior | None = None,
    ):
        """frame_size: the env's style frame; the discriminator sees its cfg.frame_features, as `reference`
        must hold them. pose_prior and stroke_prior: the pose reward weighted by cfg.w_pose (rl.pose_prior)
        and the stroke reward weighted by cfg.w_stroke (rl.stroke_prior), with the labels of the env's
        style_labels when conditioned on labels."""
        self.cfg = cfg
        self.device = torch.device(device)
        self.columns = feature_columns(cfg.frame_features, frame_size)
        # The joint positions of a frame, which the pose prior compares (none without a pose prior: a frame
        # need not be positions and velocities then).
        self.q_columns = feature_columns('q', frame_size) if pose_prior or stroke_prior else None
        frame_size = self.columns.stop - self.columns.start
        if reference.frames.shape[1] != frame_size:
            raise ValueError(
                f'reference frames hold {reference.frames.shape[1]} values, the discriminator sees '
                f'{frame_size} ({cfg.frame_features!r} of {self.columns.stop} values)'
            )
        if cfg.condition_on_label and not reference.label_names:
            raise ValueError('amp.condition_on_label needs reference windows with labels (label_names)')
        self.reference = reference
        self.num_labels = len(reference.label_names) if cfg.condition_on_label else 0
        self.num_phases = PHASES if cfg.condition_on_phase else 1
        conditioned = cfg.condition_on_label or cfg.condition_on_phase
        self.num_conditions = max(self.num_labels, 1) * self.num_phases if conditioned else 0
        self.discriminator = Discriminator(
            frame_size, cfg.sequence_length, cfg.hidden_dims, cfg.activation, cfg.normalizer_clip, self.num_conditions
        ).to(self.device)
        self.optimizer = _adam_with_decay(self.discriminator, cfg)
        self.replay = ReplayBuffer(cfg.replay_size, (cfg.sequence_length, frame_size), self.device)
        self.generator = torch.Generator(device=self.device)
        self.generator.manual_seed(int(seed) + 7907)
        self.history: StyleHistory | None = None
        self.num_envs = int(num_envs)
        self.pose_prior = pose_prior
        self.stroke_prior = stroke_prior
        # The motion terms' scale (1, or rl.success_hold's while a run holds its returns).
        self.motion_scale = 1.0
        # A label without demonstrations earns no style reward: D has no example of it, so it could only
        # teach the policy what that stroke is not (item "labels without clips" in docs/DESIGN.md).
        self.labels_with_windows = (
            torch.bincount(reference.labels, minlength=self.num_labels) > 0 if self.num_labels else None
        )
        # The normaliser starts from the demonstrations, so the first rewards are not on raw radians.
        self.discriminator.normalizer.update(reference.frames)

    def condition(self, labels: torch.Tensor | None, phases: torch.Tensor | None) -> torch.Tensor | None:
        """The discriminator's condition index [B] of label and phase indices [B] (None when unconditioned):
        label * phases + phase, so that a prior conditioned on labels alone keeps the labels' indices."""
        if not self.num_conditions:
            return None
        condition = labels * self.num_phases if self.num_labels else None
        if self.num_phases > 1:
            condition = phases if condition is None else condition + phases
        return condition

    # --- during rollouts ---------------------------------------------------------------------------
    def start(self, first_frames: torch.Tensor) -> None:
        """Every environment begins a new episode with these frames [N, D]."""
        self.history = StyleHistory(first_frames[:, self.columns], self.cfg.sequence_length)
        if self.stroke_prior is not None:
            self.stroke_prior.start(first_frames[:, self.q_columns])

    def observe(
        self,
        frames: torch.Tensor,
        dones: torch.Tensor,
        next_first_frames: torch.Tensor,
        labels: torch.Tensor | None = None,
        phases: torch.Tensor | None = None,
    ) -> torch.Tensor:
        """One policy step: frames [N, D] reached by this step (before resets), dones [N], the frames
        every environment is in now (after resets), and, for a conditioned prior, the label index [N] of the
        motion each step should be and its phase [N] (0 before the hit, 1 after; before resets). Stores the
        windows; returns the style reward [N]."""
        if self.history is None:
            raise RuntimeError('call start() with the first frames before observe()')
        if self.num_labels and labels is None:
            raise ValueError("amp.condition_on_label: the env must give each step's 'style_label'")
        if self.num_phases > 1 and phases is None:
            raise ValueError("amp.condition_on_phase: the env must give each step's 'style_phase'")
        condition = self.condition(labels, phases)
        windows = self.history.push(frames[:, self.columns])
        reward = style_reward(self.discriminator.score(windows, condition), self.cfg.style_reward)
        if self.labels_with_windows is not None:
            reward = reward * self.labels_with_windows[labels]
        self.replay.insert(windows, condition)
        done_ids = torch.nonzero(dones).squeeze(1)
        if done_ids.numel():
            self.history.restart(done_ids, next_first_frames[done_ids][:, self.columns])
        return reward

    def pose_reward(
        self, frames: torch.Tensor, time_s: torch.Tensor | None, labels: torch.Tensor | None = None
    ) -> torch.Tensor:
        """The pose prior's reward [N] for the arm states frames [N, D] reached by this step, at the env's
        style clock time_s [N] (0 without a pose prior)."""
        if self.pose_prior is None:
            return torch.zeros(frames.shape[0], device=frames.device)
        if time_s is None:
            raise ValueError("amp.w_pose: the env must give each step's 'style_time_s'")
        return self.pose_prior.reward(frames[:, self.q_columns], time_s, labels if self.num_labels else None)

    def stroke_reward(
        self,
        frames: torch.Tensor,
        stroke_end: torch.Tensor | None,
        dones: torch.Tensor,
        next_first_frames: torch.Tensor,
        labels: torch.Tensor | None = None,
    ) -> torch.Tensor:
        """The stroke prior's reward [N] (rl.stroke_prior.StrokePrior.observe; 0 without a stroke prior)."""
        if self.stroke_prior is None:
            return torch.zeros(frames.shape[0], device=frames.device)
        if stroke_end is None:
            raise ValueError("amp.w_stroke: the env must give each step's 'style_stroke_end'")
        return self.stroke_prior.observe(
            frames[:, self.q_columns],
            stroke_end,
            dones,
            next_first_frames[:, self.q_columns],
            labels if self.num_labels else None,
        )

    def mix(
        self,
        task_reward: torch.Tensor,
        style: torch.Tensor,
        style_factor: torch.Tensor | None = None,
        pose: torch.Tensor | None = None,
        stroke: torch.Tensor | None = None,
        after_touch: torch.Tensor | None = None,
    ) -> torch.Tensor:
        """r = w_task r_task + w_style r_style + w_pose r_pose + w_stroke r_stroke [N], the motion terms times
        motion_scale and the env's per-step factor [N] when it gives one.

        With after_touch [N] bool (amp.free_follow_through: the step began after the paddle's touch), two
        value streams [N, 2]: the task with the held motion terms of the steps before the touch and the
        stroke term, then the per-step motion terms of the steps after the touch at their full weight. Those
        steps cannot change the return any more (the ball is on its way), so nothing there needs holding;
        their own stream ends at the touch (the runner), so that the steps before it are not drawn to trade
        the return for a follow-through. The stroke term judges the whole stroke and stays with the held."""
        per_step = self.cfg.w_style * style
        if pose is not None:
            per_step = per_step + self.cfg.w_pose * pose
        stroke_term = torch.zeros_like(per_step) if stroke is None else self.cfg.w_stroke * stroke
        if style_factor is not None:
            per_step, stroke_term = style_factor * per_step, style_factor * stroke_term
        task = self.cfg.w_task * task_reward
        if after_touch is None:
            return task + self.motion_scale * (per_step + stroke_term)
        after = after_touch.to(per_step.dtype)
        held = task + self.motion_scale * ((1.0 - after) * per_step + stroke_term)
        return torch.stack((held, after * per_step), dim=-1)

    # --- training ----------------------------------------------------------------------------------
    def update(self) -> dict[str, float]:
        """cfg.updates_per_iteration minibatch steps of the discriminator; the means of what it logs."""
        cfg, disc = self.cfg, self.discriminator
        totals = {'loss': 0.0, 'grad_penalty': 0.0, 'd_reference': 0.0, 'd_policy': 0.0, 'accuracy': 0.0}
        for _ in range(cfg.updates_per_iteration):
            drawn_reference = self.reference.draw(cfg.batch_size, self.generator)
            drawn_policy = self.replay.draw(cfg.batch_size, self.generator)
            reference = self.reference.windows(drawn_reference)
            policy = self.replay.data[drawn_policy]
            reference_conditions = self.condition(
                self.reference.labels[drawn_reference], self.reference.phases[drawn_reference]
            )
            policy_conditions = self.replay.conditions[drawn_policy] if self.num_conditions else None
            norm_reference = disc.normalize(reference).requires_grad_(True)
            norm_policy = disc.normalize(policy)
            # The penalty is on the windows' gradient: a label is not a direction D can be smooth along.
            d_reference = disc(norm_reference, reference_conditions)
            d_policy = disc(norm_policy, policy_conditions)
            lsgan = 0.5 * ((d_reference - 1.0).square().mean() + (d_policy + 1.0).square().mean())
            (gradient,) = torch.autograd.grad(d_reference.sum(), norm_reference, create_graph=True)
            penalty = gradient.square().sum(-1).mean()
            loss = lsgan + cfg.grad_penalty * penalty
            self.optimizer.zero_grad(set_to_none=True)
            loss.backward()
            self.optimizer.step()
            # The statistics move after the step, so the loss and its penalty saw one normalisation.
            disc.normalizer.update(torch.cat((reference, policy)).detach())
            totals['loss'] += float(lsgan.detach())
            totals['grad_penalty'] += float(penalty.detach())
            totals['d_reference'] += float(d_reference.detach().mean())
            totals['d_policy'] += float(d_policy.detach().mean())
            totals['accuracy'] += 0.5 * float((d_reference > 0).float().mean() + (d_policy < 0).float().mean())
        return {f'disc/{k}': v / max(cfg.updates_per_iteration, 1) for k, v in totals.items()}

    # --- checkpoints -------------------------------------------------------------------------------
    def state_dict(self) -> dict[str, Any]:
        return {
            'discriminator': self.discriminator.state_dict(),
            'optimizer': self.optimizer.state_dict(),
            'generator': self.generator.get_state(),
        }

    def load_state_dict(self, state: dict[str, Any]) -> None:
        """Restore a checkpoint's prior. One saved without phases continues with them: its D is widened
        (`split_phases`), so it starts as it was and learns the phases from there, with a fresh optimiser
        (the widened layer has no Adam moments to resume)."""
        saved = state['discriminator']
        wanted = self.discriminator.state_dict()[FIRST_LAYER_WEIGHT].shape[1]
        if self.num_phases > 1 and saved[FIRST_LAYER_WEIGHT].shape[1] != wanted:
            saved_labels = saved[FIRST_LAYER_WEIGHT].shape[1] - (wanted - self.num_conditions)
            self.discriminator.load_state_dict(split_phases(saved, saved_labels, self.num_phases))
        else:
            self.discriminator.load_state_dict(saved)
            self.optimizer.load_state_dict(state['optimizer'])
        self.generator.set_state(state['generator'].cpu())  # generator states are CPU byte tensors


def split_phases(state: dict[str, torch.Tensor], num_labels: int, num_phases: int) -> dict[str, torch.Tensor]:
    """A discriminator state conditioned on num_labels labels (or none: 0), widened to condition on
    (label, phase) pairs that give every phase the label's old weights: D's outputs are unchanged until
    training tells the phases apart."""
    weight = state[FIRST_LAYER_WEIGHT]
    window_size = weight.shape[1] - num_labels
    if window_size <= 0:
        raise ValueError(f'a first layer of {weight.shape[1]} inputs cannot hold {num_labels} labels')
    window_columns, label_columns = weight[:, :window_size], weight[:, window_size:]
    if not num_labels:  # unconditioned: one label whose one-hot had no weight
        label_columns = torch.zeros_like(weight[:, :1])
    widened = dict(state)
    widened[FIRST_LAYER_WEIGHT] = torch.cat((window_columns, label_columns.repeat_interleave(num_phases, dim=1)), dim=1)
    return widened
