"""The pose prior: a dense reward for the demonstrated pose at the same time from the stroke's key event.

    r_pose = exp(-min_c |q - q_c[h_c + tau * rate]| / sigma)

over the clips c with the step's label (every speed factor), where q_c is clip c's joint positions at
the dataset's rate, h_c its hit frame (dataset.hit_frame: where a ball would be met) and tau the env's
style clock: the time from the step to the key event of its episode, negative before it (the task: the
time the ball needs to reach the paddle's home plane), positive after it (the time since the paddle's
touch). A frame before a clip's start is its first (the demonstrator's ready pose, where a person waits
for the ball) and one after its end its last.

With the stroke's length after the event (`follow_through_s`, the env's), the frames after it follow
each clip's follow-through to its end over that time instead, at progress min(tau / follow_through_s, 1):

    q_c[h_c + round(min(tau / follow_through_s, 1) * (F_c - 1 - h_c))]

Why. DTW pairs the last frame of a stroke with the last frame of a clip: a stroke judged up to
follow_through_s after its touch is measured against where the demonstration's follow-through ends. On
the clips' own clock the nearest clip after the touch is the slowest (a dragged follow-through has
barely begun 0.3 s after the hit), which pays a stroke for stopping at its hit, or for swinging back,
while the measure pays for finishing the follow-through. The follow-through's path is the clip's; only
its pace is the stroke's.

Why beside the discriminator. A policy that already returns balls in one style, set to learn another,
meets a fresh discriminator that tells its windows from the new demonstrations at once: its outputs pin at
-1, where the least-squares style reward is flat, and the policy gets no direction to move in (a converged
actor continued on a fresh discriminator drifted from its old style without coming nearer the new one).
A demonstrated pose to be in at each moment is a signal that never saturates, and it is what the style is
measured by: a stroke's DTW distance sums pose distances along a warping path that pairs the stroke's
frames with the clip's in order; timed by the ball, the stroke's frame at tau is paired with the clip's
frame at tau. A nearest pose without the time (tried first) barely moved the strokes: the shipped actor's
poses lie within 0.2 rad of some demonstrated pose; its strokes pass them in another order and timing.
The clip nearest at each step may change: any demonstrated take at any speed factor is a stroke to play.

A label with no clips has nothing to track: its steps earn no pose reward (0), so that the stroke such
balls get is left to the task and to the skill the policy started from.
Nothing here knows the task: the runner hands over the env's style frames, labels and clock (rl.env).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import torch


@dataclass(frozen=True)
class LabelClips:
    """The clips of one label, padded to one length: positions [C, F, J], lengths [C], hit frames [C]."""

    q_rad: torch.Tensor
    lengths: torch.Tensor
    hit_frames: torch.Tensor

    @property
    def count(self) -> int:
        return int(self.lengths.numel())


def pack_clips(clips: Sequence[tuple[np.ndarray, int]], joints: int, device: torch.device) -> LabelClips:
    """(positions [F, J], hit frame) of each clip as one LabelClips (the last frame repeats as padding)."""
    if not clips:
        empty = torch.zeros(0, dtype=torch.long, device=device)
        return LabelClips(torch.zeros(0, 1, joints, device=device), empty, empty)
    longest = max(len(q) for q, _ in clips)
    padded = np.stack([np.concatenate([q, np.repeat(q[-1:], longest - len(q), axis=0)]) for q, _ in clips])
    return LabelClips(
        torch.as_tensor(padded, dtype=torch.float32, device=device),
        torch.tensor([len(q) for q, _ in clips], dtype=torch.long, device=device),
        torch.tensor([int(h) for _, h in clips], dtype=torch.long, device=device),
    )


class PosePrior:
    """Demonstrated clips per label, and the pose reward of arm states against them on the env's clock."""

    def __init__(
        self,
        clips_by_label: Sequence[Sequence[tuple[np.ndarray, int]]],
        sigma_rad: float,
        rate_hz: float,
        device: torch.device | str = 'cpu',
        follow_through_s: float | None = None,
    ):
        """clips_by_label: for each label index, its clips as (joint positions [F, J], hit frame) (may be none).
        follow_through_s: the stroke's length after the key event (None: the clips' own clock after it too)."""
        if not sigma_rad > 0.0 or not rate_hz > 0.0:
            raise ValueError(f'the pose prior needs a positive sigma and rate, got {sigma_rad} and {rate_hz}')
        if follow_through_s is not None and not follow_through_s > 0.0:
            raise ValueError(f'the pose prior needs a positive follow-through, got {follow_through_s}')
        clips = [c for label in clips_by_label for c in label]
        if not clips:
            raise ValueError('the pose prior has no demonstrated clip under any label')
        joints = {np.asarray(q).shape[1] for q, _ in clips}
        if len(joints) != 1 or any(np.asarray(q).ndim != 2 or not 0 <= h < len(q) for q, h in clips):
            raise ValueError('each clip must be (frames, joints) positions of one width with its hit frame inside')
        self.device = torch.device(device)
        self.sigma_rad = float(sigma_rad)
        self.rate_hz = float(rate_hz)
        self.follow_through_s = None if follow_through_s is None else float(follow_through_s)
        width = joints.pop()
        self.labels = [
            pack_clips([(np.asarray(q, dtype=np.float32), h) for q, h in label], width, self.device)
            for label in clips_by_label
        ]

    @classmethod
    def from_dataset(
        cls,
        dataset,
        label_names: Sequence[str],
        sigma_rad: float,
        device: torch.device | str = 'cpu',
        follow_through_s: float | None = None,
    ) -> 'PosePrior':
        """The clips of a stylepong_policy.training.dataset.ReferenceDataset (every speed factor), grouped by the
        labels of label_names; () : one group of every clip."""
        from stylepong_policy.training.dataset import hit_frame

        def clips_of(chosen) -> list[tuple[np.ndarray, int]]:
            clips = [dataset.clip(int(c)) for c in chosen]
            return [(clip.q, hit_frame(clip.qd)) for clip in clips]

        groups = [dataset.select(labels=[name]) for name in label_names] or [np.arange(dataset.num_clips)]
        return cls([clips_of(chosen) for chosen in groups], sigma_rad, dataset.rate_hz, device, follow_through_s)

    @property
    def labels_with_clips(self) -> torch.Tensor:
        """[K] bool: the labels that have demonstrated clips."""
        return torch.tensor([clips.count > 0 for clips in self.labels], device=self.device)

    def reference_distance_rad(
        self, q_rad: torch.Tensor, time_s: torch.Tensor, labels: torch.Tensor | None = None
    ) -> torch.Tensor:
        """[N] distance of each arm pose q_rad [N, J] to the nearest of its label's clips at the same time
        from the key event time_s [N] (labels [N] label indices; None: label 0); inf for a label without."""
        n = q_rad.shape[0]
        distance = torch.full((n,), math.inf, device=self.device)
        labels = torch.zeros(n, dtype=torch.long, device=self.device) if labels is None else labels
        for label, clips in enumerate(self.labels):
            rows = torch.nonzero(labels == label).squeeze(1)
            if not rows.numel() or not clips.count:
                continue
            frames = self._reference_frames(clips, time_s[rows])  # [n, C]
            reference = clips.q_rad[torch.arange(clips.count, device=self.device)[None, :], frames]  # [n, C, J]
            distance[rows] = torch.linalg.vector_norm(reference - q_rad[rows, None, :], dim=2).amin(dim=1)
        return distance

    def _reference_frames(self, clips: LabelClips, time_s: torch.Tensor) -> torch.Tensor:
        """[n, C] each clip's frame at the style clock time_s [n] (the module's formulas)."""
        hits, last = clips.hit_frames[None, :], clips.lengths[None, :] - 1
        on_clip_clock = hits + torch.round(time_s * self.rate_hz).long()[:, None]
        frames = torch.minimum(on_clip_clock.clamp(min=0), last)
        if self.follow_through_s is None:
            return frames
        progress = (time_s / self.follow_through_s).clamp(0.0, 1.0)[:, None]
        through = hits + torch.round(progress * (last - hits).to(progress.dtype)).long()
        return torch.where(time_s[:, None] > 0.0, through, frames)

    def reward(self, q_rad: torch.Tensor, time_s: torch.Tensor, labels: torch.Tensor | None = None) -> torch.Tensor:
        """[N] exp(-distance / sigma) to the label's demonstrated pose at that time (0 for a label without)."""
        return torch.exp(-self.reference_distance_rad(q_rad, time_s, labels) / self.sigma_rad)
