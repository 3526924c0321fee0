"""learn_style's progress: one bar per stage, with the stage's name and an ETA (tqdm).

The training stage is budgeted in time, so its bar counts the run's seconds of training against the budget
(a resumed run's bar starts at the time trained before) and its ETA is the budget left; the other stages
count their evaluations. On a terminal the bar redraws in place; in a log file (nohup) it writes a line
every LOG_INTERVAL_S.
"""

from __future__ import annotations

import sys

from tqdm import tqdm

LOG_INTERVAL_S = 30.0


class StageBar:
    """A context manager around tqdm for one stage of learn_style."""

    def __init__(self, stage: str, total: float, unit: str = 's', initial: float = 0.0):
        """initial: how much of total was done before (a resumed run's training time)."""
        self.stage = stage
        self.total = float(total)
        self.initial = min(max(float(initial), 0.0), self.total)
        self.unit = unit
        self.bar: tqdm | None = None

    def __enter__(self) -> 'StageBar':
        tty = sys.stderr.isatty()
        fmt = '{desc} {percentage:3.0f}%|{bar}| {n:.0f}/{total:.0f} ' + self.unit + ' [{elapsed}<{remaining}{postfix}]'
        self.bar = tqdm(
            total=self.total,
            initial=self.initial,
            desc=f'[learn_style] {self.stage}',
            bar_format=fmt,
            dynamic_ncols=True,
            mininterval=0.5 if tty else LOG_INTERVAL_S,
            file=sys.stderr,
        )
        return self

    def __exit__(self, *exc) -> None:
        if self.bar is not None:
            self.bar.close()

    def advance(self, amount: float) -> None:
        """Move the bar on, never past its total."""
        if self.bar is not None:
            self.bar.update(max(0.0, min(amount, self.total - self.bar.n)))

    def iteration(self, stats: dict) -> None:
        """The runner's per-iteration callback: the run's training time so far and a few figures."""
        if self.bar is not None:
            if 'wall_time_s' in stats:
                self.advance(float(stats['wall_time_s']) - self.bar.n)
            success = stats.get('success_rate')
            scale = stats.get('motion_scale')
            self.bar.set_postfix_str(
                f'it {stats.get("iteration")}'
                + (f', success {success:.3f}' if isinstance(success, float) else '')
                + f', pose {stats.get("step_reward/pose", float("nan")):.3f}'
                + (f', style scale {scale:.2f}' if scale is not None else ''),
                refresh=False,
            )
