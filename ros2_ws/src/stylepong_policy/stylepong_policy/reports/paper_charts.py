"""Bar charts of the paper's tables, ours beside the paper's figures (PNG, for results/README.md).

Each chart carries its setting in its title (what world, which seeds, how many balls), since a bar
without it cannot be compared with anything. Inputs are plain dicts made by paper_tables.
"""

from __future__ import annotations

import os
import pathlib
from collections.abc import Sequence

import numpy as np

from stylepong_description.robot_cell import STROKE_LABELS as DIRECTIONS
from stylepong_policy import png

PAPER_COLOUR = '#9aa5b1'
OURS_COLOUR = '#1f6fb2'


def _paired_bars(
    ax,
    labels: Sequence[str],
    paper: Sequence[float | None],
    ours: Sequence[float | None],
    ours_err: Sequence[float | None] | None = None,
    percent: bool = True,
) -> None:
    """Paper and ours side by side for each label; a missing value is left out and marked."""
    x = np.arange(len(labels))
    width = 0.38
    scale = 100.0 if percent else 1.0

    def heights(values):
        return [np.nan if v is None else v * scale for v in values]

    errors = None if ours_err is None else [0.0 if e is None else e * scale for e in ours_err]
    ax.bar(x - width / 2, heights(paper), width, color=PAPER_COLOUR, label='paper')
    bars = ax.bar(x + width / 2, heights(ours), width, color=OURS_COLOUR, label='ours', yerr=errors, capsize=3)
    for bar, value in zip(bars, ours):
        if value is not None:
            ax.annotate(
                f'{value * scale:.1f}',
                (bar.get_x() + bar.get_width() / 2, bar.get_height()),
                ha='center',
                va='bottom',
                fontsize=8,
            )
    for i, value in enumerate(paper):
        if value is None:
            ax.annotate('n/a', (x[i] - width / 2, 0), ha='center', va='bottom', fontsize=8)
    ax.set_xticks(x, labels)
    ax.legend(loc='lower right', fontsize=8)


def success_chart(
    path: str | os.PathLike,
    labels: Sequence[str],
    paper: Sequence[float | None],
    ours: Sequence[float | None],
    ours_std: Sequence[float | None],
    title: str,
    setting: str,
) -> pathlib.Path:
    """Success rates (fractions) of several methods or speed bands, paper beside ours."""
    plt = png.headless_pyplot()
    figure, ax = plt.subplots(figsize=(max(5.5, 1.4 * len(labels) + 2), 4.2))
    _paired_bars(ax, labels, paper, ours, ours_std)
    ax.set_ylabel('success rate (%)')
    ax.set_ylim(0, 105)
    ax.set_title(f'{title}\n{setting}', fontsize=9)
    return png.save_chart(figure, path)


def dtw_chart(
    path: str | os.PathLike,
    paper_ratio: Sequence[float],
    ours_ratio: Sequence[float | None],
    ours_dtw: dict[str, Sequence[float | None]],
    setting: str,
) -> pathlib.Path:
    """Left: the ratio amp/ppo of DTW per direction (comparable across conventions); right: our DTW."""
    plt = png.headless_pyplot()
    figure, (left, right) = plt.subplots(1, 2, figsize=(10, 4.2))
    _paired_bars(left, DIRECTIONS, paper_ratio, ours_ratio, percent=False)
    left.set_ylabel('DTW amp / DTW ppo')
    left.axhline(1.0, color='k', linewidth=0.6)
    left.set_title('ratio of DTW distances, amp / ppo (below 1: amp closer to the demonstrations)', fontsize=9)
    x = np.arange(len(DIRECTIONS))
    width = 0.8 / max(len(ours_dtw), 1)
    for k, (name, values) in enumerate(ours_dtw.items()):
        right.bar(x - 0.4 + width * (k + 0.5), [np.nan if v is None else v for v in values], width, label=name)
    right.set_xticks(x, DIRECTIONS)
    right.set_ylabel('DTW distance (rad, summed along the path)')
    right.set_title('our DTW per direction', fontsize=9)
    right.legend(fontsize=8)
    figure.suptitle(setting, fontsize=9)
    return png.save_chart(figure, path)


def smoothness_chart(
    path: str | os.PathLike, rows: dict[str, dict[str, dict | None]], reference: dict[str, dict | None], setting: str
) -> pathlib.Path:
    """Three panels (peak speed, peak acceleration, mean |jerk|), bars per actor and direction; the
    demonstrations' values as ticks."""
    plt = png.headless_pyplot()
    measures = (
        ('peak_joint_speed_rad_s', 'peak joint speed (rad/s)'),
        ('peak_joint_acceleration_rad_s2', 'peak joint acceleration (rad/s²)'),
        ('mean_abs_jerk_rad_s3', 'mean |jerk| (rad/s³)'),
    )
    figure, axes = plt.subplots(1, 3, figsize=(13, 4.2))
    x = np.arange(len(DIRECTIONS))
    width = 0.8 / max(len(rows), 1)
    for ax, (key, label) in zip(axes, measures):
        for k, (name, table) in enumerate(rows.items()):
            values = [np.nan if table.get(d) is None else table[d][key] for d in DIRECTIONS]
            ax.bar(x - 0.4 + width * (k + 0.5), values, width, label=name)
        ref = [np.nan if reference.get(d) is None else reference[d][key] for d in DIRECTIONS]
        ax.scatter(x, ref, marker='_', s=600, color='k', label='demonstrations (x1)', zorder=3)
        ax.set_xticks(x, DIRECTIONS)
        ax.set_title(label, fontsize=9)
    handles, labels = axes[0].get_legend_handles_labels()
    figure.legend(handles, labels, loc='lower center', ncol=len(labels), fontsize=8)
    figure.suptitle(setting, fontsize=9)
    return png.save_chart(figure, path, layout_rect=(0, 0.07, 1, 1))
