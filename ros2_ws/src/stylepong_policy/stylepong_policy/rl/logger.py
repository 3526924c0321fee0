"""Training logs: one CSV row and TensorBoard scalars per iteration, and the learning-curve plot.

The CSV is the durable record (it survives a resume: rows past the resumed iteration are dropped so
the file never holds two histories); TensorBoard is for watching a run live.
"""

from __future__ import annotations

import csv
import lzma
import math
import pathlib
from typing import Any

from stylepong_policy import png

CSV_NAME = 'progress.csv'
TENSORBOARD_DIR = 'tensorboard'


class TrainingLog:
    """The training log of a run: a CSV row per iteration and, optionally, TensorBoard events."""

    def __init__(self, run_dir: str | pathlib.Path, start_iteration: int, tensorboard: bool = True):
        self.run_dir = pathlib.Path(run_dir)
        self.run_dir.mkdir(parents=True, exist_ok=True)
        self.csv_path = self.run_dir / CSV_NAME
        self.fieldnames: list[str] | None = None
        self._truncate_csv(start_iteration)
        self.writer = None
        if tensorboard:
            from torch.utils.tensorboard import SummaryWriter

            # purge_step drops events a previous session logged past the checkpoint we resume from.
            self.writer = SummaryWriter(
                log_dir=str(self.run_dir / TENSORBOARD_DIR), purge_step=start_iteration if start_iteration > 0 else None
            )

    def _truncate_csv(self, start_iteration: int) -> None:
        if not self.csv_path.exists():
            return
        fieldnames, rows = _read_rows(self.csv_path)
        if not fieldnames:
            return
        self.fieldnames = fieldnames
        self._rewrite([row for row in rows if int(float(row['iteration'])) <= start_iteration])

    def _rewrite(self, rows: list[dict[str, str]]) -> None:
        with open(self.csv_path, 'w', newline='') as f:
            writer = csv.DictWriter(f, fieldnames=self.fieldnames, restval='')
            writer.writeheader()
            writer.writerows(rows)

    def write(self, row: dict[str, Any]) -> None:
        """Append one iteration. A column first seen now (episode statistics appear only once episodes
        have ended) widens the file, earlier rows left empty there."""
        new_file = self.fieldnames is None
        if new_file:
            self.fieldnames = list(row)
        new_columns = [key for key in row if key not in self.fieldnames]
        if new_columns:
            self.fieldnames += new_columns
            self._rewrite(_read_rows(self.csv_path)[1])
        with open(self.csv_path, 'a', newline='') as f:
            writer = csv.DictWriter(f, fieldnames=self.fieldnames)
            if new_file:
                writer.writeheader()
            writer.writerow({k: _csv_value(row.get(k)) for k in self.fieldnames})
        if self.writer is not None:
            step = int(row['iteration'])
            for key, value in row.items():
                if key != 'iteration' and isinstance(value, (int, float)) and math.isfinite(value):
                    self.writer.add_scalar(_tensorboard_tag(key), value, step)

    def close(self) -> None:
        if self.writer is not None:
            self.writer.flush()
            self.writer.close()
            self.writer = None


def _csv_value(value: Any) -> Any:
    if value is None:
        return ''
    if isinstance(value, float):
        return f'{value:.6g}'
    return value


def _tensorboard_tag(key: str) -> str:
    if '/' in key:
        return key
    group = (
        'perf'
        if key
        in (
            'samples_per_s',
            'iteration_time_s',
            'world_s',
            'policy_s',
            'learn_s',
            'world_share',
            'wall_time_s',
            'env_steps',
        )
        else 'loss'
        if key in ('value_loss', 'surrogate_loss', 'entropy', 'kl', 'clip_fraction', 'learning_rate', 'action_std')
        else 'train'
    )
    return f'{group}/{key}'


def _read_rows(csv_path: pathlib.Path) -> tuple[list[str], list[dict[str, str]]]:
    # A shipped run's CSV is kept xz-compressed (ship_run: a third of the size); a run's own is appended to, plain.
    opener = lzma.open if csv_path.suffix == '.xz' else open
    with opener(csv_path, 'rt', newline='') as f:
        reader = csv.DictReader(f)
        rows = list(reader)
        return list(reader.fieldnames or []), rows


def read_progress(csv_path: str | pathlib.Path) -> dict[str, list[float]]:
    """Columns of a progress CSV as float lists (empty cells become NaN); a .csv.xz is read as its CSV."""
    fieldnames, rows = _read_rows(pathlib.Path(csv_path))
    if not rows:
        return {}
    return {key: [float(r[key]) if r[key] not in ('', None) else math.nan for r in rows] for key in fieldnames}


RATE_COLUMNS = (('success_rate', 'success rate'), ('hit_rate', 'hit rate'))
STYLE_COLUMNS = (
    ('step_reward/style', 'style reward per step'),
    ('disc/d_reference', 'D on reference'),
    ('disc/d_policy', 'D on policy'),
)


def plot_learning_curve(csv_path: str | pathlib.Path, png_path: str | pathlib.Path, title: str = '') -> None:
    """Success and hit rates (where the env logs them), mean episode return and, for a run with a motion
    prior, the style reward and the discriminator's outputs, against samples, with wall time on top."""
    import matplotlib

    matplotlib.use('Agg')
    import matplotlib.pyplot as plt

    data = read_progress(csv_path)
    if not data:
        raise ValueError(f'{csv_path} holds no iterations to plot')
    samples_m = [s / 1e6 for s in data['env_steps']]
    style = [(key, label) for key, label in STYLE_COLUMNS if key in data]
    panels = 3 if style else 2
    fig, axes = plt.subplots(panels, 1, figsize=(8, 3.5 * panels), sharex=True)
    ax_rate, ax_ret = axes[0], axes[1]
    for key, label in RATE_COLUMNS:
        if key in data:
            ax_rate.plot(samples_m, data[key], label=label)
    ax_rate.set_ylim(-0.02, 1.02)
    ax_rate.set_ylabel('rate over episodes per iteration')
    ax_rate.grid(True, alpha=0.3)
    ax_rate.legend(loc='lower right')
    ax_ret.plot(samples_m, data['mean_return'], color='tab:green')
    ax_ret.set_ylabel('mean episode return')
    ax_ret.grid(True, alpha=0.3)
    if style:
        for key, label in style:
            axes[2].plot(samples_m, data[key], label=label)
        axes[2].set_ylabel('motion prior')
        axes[2].grid(True, alpha=0.3)
        axes[2].legend(loc='lower right')
    axes[-1].set_xlabel('samples (millions)')
    hours = [t / 3600.0 for t in data['wall_time_s']]
    top = ax_rate.secondary_xaxis(
        'top', functions=(lambda x: _interp(x, samples_m, hours), lambda h: _interp(h, hours, samples_m))
    )
    top.set_xlabel('training wall time (h)')
    if title:
        fig.suptitle(title)
    fig.tight_layout()
    png.save_figure(fig, png_path, dpi=120)
    plt.close(fig)


def _interp(x, xs: list[float], ys: list[float]):
    import numpy as np

    if len(xs) < 2:
        return np.asarray(x, dtype=float) * 0.0 + (ys[0] if ys else 0.0)
    return np.interp(x, xs, ys)
