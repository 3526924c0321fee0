"""The stroke prior: a reward at the end of each stroke for its DTW distance to the nearest demonstration.

    r_stroke = exp(-DTW(stroke, nearest clip of its label) / (sigma * frames))    once, at the stroke's end

The stroke is each episode's joint positions from its first frame to the step the env marks as the
stroke's end (rl.env's 'style_stroke_end'; the task: FOLLOW_THROUGH_S after the paddle's touch, or the
ball's verdict), exactly as `evaluate` cuts strokes; the clips are all of the label's, every speed factor,
and the distance is the one `evaluate --dtw` reports (stylepong_policy.evaluation.style_metrics: dtaidistance's DTW,
Euclidean local cost, not normalised). Dividing by the stroke's frames makes sigma a distance per frame.

Why. The discriminator and the pose prior judge windows and poses; what a style is measured by is the
whole stroke warped onto a demonstration, which lets a stroke be early or late where the ball asks it to
be and still look demonstrated. This reward is that measure: sparse (one per ball, like the task's
success), but exact, where the per-step terms are only correlated with it. A label with no clips has no
distance: its strokes earn nothing.
Nothing here knows the task: the runner hands over the env's style frames, labels and stroke ends.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import torch

from stylepong_policy.evaluation import style_metrics

# A stroke longer than this (frames at the policy rate; 5 s at 60 Hz) keeps its first MAX_FRAMES frames.
MAX_FRAMES = 300


class StrokePrior:
    """Each environment's stroke so far, and its reward against the demonstrations when it ends."""

    def __init__(self, clips_by_label: Sequence[Sequence[np.ndarray]], sigma_rad: float, num_envs: int, joints: int):
        """clips_by_label: for each label index, its clips' joint positions [F, J] (may be none)."""
        if not sigma_rad > 0.0:
            raise ValueError(f'the stroke prior needs a positive sigma, got {sigma_rad}')
        if not any(len(label) for label in clips_by_label):
            raise ValueError('the stroke prior has no demonstrated clip under any label')
        self.sigma_rad = float(sigma_rad)
        self.clips = [[np.ascontiguousarray(c, dtype=np.float64) for c in label] for label in clips_by_label]
        self.frames = np.zeros((num_envs, MAX_FRAMES, joints))
        self.lengths = np.zeros(num_envs, dtype=np.int64)
        self.scored = np.zeros(num_envs, dtype=bool)

    @classmethod
    def from_dataset(cls, dataset, label_names: Sequence[str], sigma_rad: float, num_envs: int) -> 'StrokePrior':
        """The clips of a stylepong_policy.training.dataset.ReferenceDataset (every speed factor) grouped by the labels
        of label_names; () : one group of every clip."""
        groups = [dataset.select(labels=[name]) for name in label_names] or [np.arange(dataset.num_clips)]
        return cls(
            [[dataset.clip(int(c)).q for c in chosen] for chosen in groups], sigma_rad, num_envs, dataset.q.shape[1]
        )

    @property
    def labels_with_clips(self) -> list[bool]:
        return [bool(label) for label in self.clips]

    def start(self, first_q_rad: torch.Tensor) -> None:
        """Every environment begins a stroke at these joint positions [N, J]."""
        self.frames[:, 0] = first_q_rad.detach().cpu().numpy()
        self.lengths[:] = 1
        self.scored[:] = False

    def distance_rad(self, stroke_rad: np.ndarray, label: int) -> float | None:
        """DTW distance of a stroke [F, J] to the nearest clip of the label (None: the label has none)."""
        clips = self.clips[label]
        if not clips:
            return None
        stroke = np.ascontiguousarray(stroke_rad, dtype=np.float64)
        return min(style_metrics.dtw_distance_rad(stroke, clip) for clip in clips)

    def observe(
        self,
        q_rad: torch.Tensor,
        stroke_end: torch.Tensor,
        dones: torch.Tensor,
        next_first_q_rad: torch.Tensor,
        labels: torch.Tensor | None = None,
    ) -> torch.Tensor:
        """One policy step: the joint positions reached [N, J] (before resets), which strokes end with it,
        which episodes ended, the new episodes' first positions [N, J] (after resets) and the steps' labels
        [N]. Returns the reward [N]: the stroke reward where a stroke ended now, 0 elsewhere."""
        q = q_rad.detach().cpu().numpy()
        room = self.lengths < MAX_FRAMES
        rows = np.flatnonzero(room & ~self.scored)
        self.frames[rows, self.lengths[rows]] = q[rows]
        self.lengths[rows] += 1
        done = dones.detach().cpu().numpy().astype(bool)
        ending = np.flatnonzero((stroke_end.detach().cpu().numpy().astype(bool) | done) & ~self.scored)
        reward = np.zeros(len(q), dtype=np.float32)
        label_of = np.zeros(len(q), dtype=np.int64) if labels is None else labels.detach().cpu().numpy()
        for env in ending:
            stroke = self.frames[env, : self.lengths[env]]
            distance = self.distance_rad(stroke, int(label_of[env]))
            if distance is not None:
                reward[env] = np.exp(-distance / (self.sigma_rad * len(stroke)))
        self.scored[ending] = True
        restarted = np.flatnonzero(done)
        if len(restarted):
            self.frames[restarted, 0] = next_first_q_rad.detach().cpu().numpy()[restarted]
            self.lengths[restarted] = 1
            self.scored[restarted] = False
        return torch.as_tensor(reward, device=q_rad.device)
