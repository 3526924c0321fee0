"""Running mean/variance observation normalisation (a torch module, so it is saved and exported with the actor)."""

from __future__ import annotations

import torch
from torch import nn


class RunningNormalizer(nn.Module):
    """y = clamp((x - mean) / sqrt(var + eps), -clip, clip), with mean and var tracked over all samples seen.

    The statistics are buffers: they travel in state_dicts (checkpoints) and are frozen into the
    exported TorchScript actor as constants, so the deployed actor needs no separate statistics file.
    Updates use Chan et al.'s parallel formula, exact for any batch split.
    """

    def __init__(self, size: int, epsilon: float = 1e-8, clip: float = 10.0):
        super().__init__()
        self.epsilon = float(epsilon)
        self.clip = float(clip)
        self.register_buffer('mean', torch.zeros(size))
        self.register_buffer('var', torch.ones(size))
        # float64: after ~1e9 samples a float32 count would stop incrementing.
        self.register_buffer('count', torch.zeros((), dtype=torch.float64))

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return torch.clamp((x - self.mean) / torch.sqrt(self.var + self.epsilon), -self.clip, self.clip)

    @torch.jit.unused
    def update(self, x: torch.Tensor) -> None:
        """Fold a batch [B, size] into the running statistics."""
        x = x.detach().reshape(-1, self.mean.shape[0])
        batch_count = x.shape[0]
        if batch_count == 0:
            return
        batch_mean = x.mean(0)
        batch_var = x.var(0, unbiased=False)
        total = self.count + batch_count
        new_weight = (batch_count / total).to(self.mean.dtype)
        delta = batch_mean - self.mean
        m2 = self.var * (1.0 - new_weight) + batch_var * new_weight + delta.square() * new_weight * (1.0 - new_weight)
        self.mean.add_(delta * new_weight)
        self.var.copy_(m2)
        self.count.copy_(total)
