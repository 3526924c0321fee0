"""The experiment behind config/amp.yaml's sequence_length: how well a discriminator of each window
length L tells the demonstrations from two kinds of wrong motion.

    ros2 run stylepong_policy amp_sequence_length [--out results/amp_sequence_length.md] [--lengths 2,3,4,6,8]

For each L, a fresh discriminator (config/amp.yaml's network, normaliser, weight decay, gradient
penalty; batch 512) trains for --steps LSGAN steps on reference windows of the dataset built from
ros2_ws/bags against one kind of negative, then scores fresh samples:
  shuffled  each frame from its own random reference window: every pose and velocity is demonstrated,
            but the window is no motion (what a policy that holds demonstrated poses without moving
            through them produces);
  slowed    the original clips played at half speed (what a policy that swings like the demonstrations
            but too slowly produces), against the original clips only.
The figure is the balanced accuracy (mean of the two classes' hit rates, 0.5 = chance), mean over
--seeds seeds. Written as Markdown by this script; nothing in it is typed by hand.
"""

from __future__ import annotations

import argparse
import pathlib
import sys
import tempfile

import numpy as np
import torch

from stylepong_common.command_line import write_lines
from stylepong_policy import paths


def shuffled(reference, count: int) -> torch.Tensor:
    """Negative windows: each frame of a window drawn from a different reference window."""
    return torch.stack([reference.sample(count)[:, i] for i in range(reference.length)], dim=1)


def slowed(reference, count: int) -> torch.Tensor:
    """Reference windows at half speed: frames half a frame apart (interpolated), velocities halved."""
    starts = reference.starts[torch.randint(reference.num_windows, (count,))].float()
    times = starts[:, None] + 0.5 * torch.arange(reference.length).float()[None, :]
    lower = times.floor().long().clamp(max=reference.frames.shape[0] - 2)
    frac = (times - lower)[..., None]
    frames = reference.frames[lower] * (1 - frac) + reference.frames[lower + 1] * frac
    half = frames.shape[-1] // 2
    return torch.cat((frames[..., :half], 0.5 * frames[..., half:]), dim=-1)


def balanced_accuracy(dataset, length: int, negative: str, steps: int, seed: int) -> float:
    """Train a discriminator on windows of `length` against one kind of negative; its balanced accuracy."""
    from stylepong_policy.rl.amp import MotionPrior, ReferenceMotion
    from stylepong_policy.rl.config import load_config
    from stylepong_policy.training.train import default_config_path

    torch.manual_seed(seed)
    cfg = load_config(default_config_path('amp')).amp
    cfg.sequence_length, cfg.batch_size, cfg.updates_per_iteration = length, 512, 1
    reference = ReferenceMotion.from_dataset(dataset, length, [1] if negative == 'slowed' else None)
    prior = MotionPrior(cfg, reference, dataset.states().shape[1], num_envs=1, device='cpu', seed=seed)
    make = shuffled if negative == 'shuffled' else slowed
    for _ in range(steps):
        prior.replay.size = 0
        prior.replay.insert(make(reference, cfg.batch_size))
        prior.update()
    with torch.no_grad():
        d_reference = prior.discriminator.score(reference.sample(4000))
        d_negative = prior.discriminator.score(make(reference, 4000))
    return 0.5 * float((d_reference > 0).float().mean() + (d_negative < 0).float().mean())


def main(argv: list[str] | None = None) -> int:
    """Measure the accuracy per window length and write the results page."""
    parser = argparse.ArgumentParser(prog='amp_sequence_length', description=__doc__.split('\n\n')[0])
    parser.add_argument('--out', type=pathlib.Path, default=paths.RESULTS / 'amp_sequence_length.md')
    parser.add_argument('--lengths', default='2,3,4,6,8')
    parser.add_argument('--steps', type=int, default=300)
    parser.add_argument('--seeds', type=int, default=3)
    args = parser.parse_args(argv)
    torch.set_num_threads(2)
    from stylepong_policy.training.dataset import ReferenceDataset
    from stylepong_policy.training.train import build_shipped_dataset

    with tempfile.TemporaryDirectory() as tmp:
        dataset = ReferenceDataset.load(build_shipped_dataset(pathlib.Path(tmp) / 'dataset.npz'))
    lengths = [int(x) for x in args.lengths.split(',')]
    rows = []
    for length in lengths:
        row = {}
        for negative in ('shuffled', 'slowed'):
            scores = [balanced_accuracy(dataset, length, negative, args.steps, seed) for seed in range(args.seeds)]
            row[negative] = (float(np.mean(scores)), float(np.std(scores)))
        rows.append((length, row))
        print(f'L={length}: {row}', file=sys.stderr, flush=True)
    lines = [
        '# Discriminator window length',
        '',
        f'Written by `ros2 run stylepong_policy amp_sequence_length` (see its docstring): balanced accuracy of a '
        f'discriminator trained {args.steps} LSGAN steps on windows of L arm states of the dataset built '
        f'from `ros2_ws/bags`, against shuffled or half-speed windows; mean +- std over {args.seeds} seeds, '
        f'fresh samples, CPU. 0.5 is chance.',
        '',
        '| L (frames at 60 Hz) | window (ms) | shuffled | slowed x0.5 |',
        '|---|---|---|---|',
    ]
    for length, row in rows:
        lines.append(
            f'| {length} | {1000 * length / 60:.0f} | {row["shuffled"][0]:.3f} +- {row["shuffled"][1]:.3f} | '
            f'{row["slowed"][0]:.3f} +- {row["slowed"][1]:.3f} |'
        )
    write_lines(args.out, lines)
    return 0


if __name__ == '__main__':
    sys.exit(main())
