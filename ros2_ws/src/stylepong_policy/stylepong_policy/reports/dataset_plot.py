"""A figure of a reference dataset for a person to look at: every clip's joint trajectories.

One row per original clip, one column per speed factor (original, x2, x3, ...); each panel shows the
joint positions against playback time at the dataset's rate, so a sped-up clip is visibly shorter.
"""

from __future__ import annotations

import os
import pathlib

import numpy as np

from stylepong_policy import png
from stylepong_policy.training.dataset import ReferenceDataset

MAX_ROWS = 40  # beyond this a figure is unreadable; the title says how many were left out


def plot_dataset(dataset: ReferenceDataset, path: str | os.PathLike) -> pathlib.Path:
    """Plot the original clips and their sped-up versions to an image file; returns its path."""
    import matplotlib

    matplotlib.use('Agg')  # headless: no display on the machines that build datasets
    import matplotlib.pyplot as plt

    path = pathlib.Path(path)
    originals = [int(i) for i in np.flatnonzero(dataset.speed_factor == 1)]
    factors = sorted({int(k) for k in dataset.speed_factor})
    rows = originals[:MAX_ROWS]
    n_rows, n_cols = max(len(rows), 1), max(len(factors), 1)
    figure, axes = plt.subplots(
        n_rows, n_cols, figsize=(3.2 * n_cols + 1.5, 2.2 * n_rows + 0.8), squeeze=False, sharey='row'
    )
    for row, original in enumerate(rows):
        versions = {int(dataset.speed_factor[c]): c for c in np.flatnonzero(dataset.original == original)}
        versions.setdefault(1, original)
        longest_s = dataset.clip_length[original] / dataset.rate_hz
        for col, factor in enumerate(factors):
            ax = axes[row][col]
            clip_index = versions.get(factor)
            if clip_index is None:
                ax.set_axis_off()
                continue
            clip = dataset.clip(clip_index)
            playback_s = np.arange(len(clip)) / dataset.rate_hz
            for j, name in enumerate(dataset.joint_names):
                ax.plot(playback_s, clip.q[:, j], lw=1.0, label=name)
            ax.set_xlim(0, max(longest_s, 1.0 / dataset.rate_hz))
            ax.grid(alpha=0.3)
            if row == 0:
                ax.set_title('original' if factor == 1 else f'x{factor}')
            if col == 0:
                source = pathlib.PurePath(str(dataset.source[original]).rsplit(':', 1)[0]).name
                ax.set_ylabel(f'{dataset.label[original]}\n{source}\nq (rad)', fontsize=8)
            if row == n_rows - 1:
                ax.set_xlabel(f'playback time at {dataset.rate_hz:g} Hz (s)')
    if rows:
        handles, names = axes[0][0].get_legend_handles_labels()
        figure.legend(handles, names, loc='lower center', ncol=len(names), fontsize=7, frameon=False)
    left_out = len(originals) - len(rows)
    figure.suptitle(
        f'{len(originals)} original clip(s), {dataset.num_clips} clips in all'
        + (f' ({left_out} originals not shown)' if left_out else '')
    )
    figure.tight_layout(rect=(0, 0.6 / (2.2 * n_rows + 0.8), 1, 1))
    path.parent.mkdir(parents=True, exist_ok=True)
    png.save_figure(figure, path, dpi=80)
    plt.close(figure)
    return path
