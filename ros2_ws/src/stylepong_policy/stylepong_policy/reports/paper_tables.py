"""`ros2 run stylepong_policy paper_tables --out results/`: the paper's evaluation, re-run on our actors.

    paper_tables --out results/ [--actors ppo=PATH,amp-noaug=PATH,amp=PATH] [--models-dir DIR]
                 [--seeds 10] [--balls 200] [--first-seed 1000] [--band-first-seed 2000]
                 [--dataset DATASET.npz | --bags ros2_ws/bags] [--no-figure] [--figure-direction forward]
                 [--save-strokes] [--device cpu] [--num-threads 2]

Evaluates the three shipped actors (models/ppo_actor.pt, amp_noaug_actor.pt, amp_actor.pt; --actors
replaces any of them, e.g. to let the PPO actor stand in while the others are trained) with
stylepong_policy.evaluation.evaluate in one process and writes to --out:
  README.md            Tables I-III of "Stylized Table Tennis Robots Skill Learning with Incomplete Human
                       Demonstrations" with the paper's figures beside ours, smoothness and per-direction
                       results, Table IV (sim2sim) from the sim2sim_*.json files found in --out, Fig. 2
  paper_tables.json    every figure in it, machine-readable (paths as given, never absolute)
  table1_success.png, table2_dtw.png, table3_speed.png, smoothness.png, strokes.png (Fig. 2)
  reference_dataset.npz  the DTW references, when built here from --bags
  strokes_<actor>_<band>.npz  with --save-strokes: every stroke (stylepong_policy.evaluation.strokes layout)
Setting (each table states it too): the batched world, nominal (no randomisation, no sensing noise),
deterministic actors; Tables I, II: seeds first-seed.. x balls, all speeds 4.0-6.6 m/s; Table III:
seeds band-first-seed.. x balls in the low (4.0-4.8) and high (5.8-6.6 m/s) bands.
Exit status 0 when written, 2 when an actor is missing or does not load, or for bad arguments.
"""

from __future__ import annotations

import argparse
import contextlib
import datetime
import io
import json
import os
import pathlib
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import torch

from stylepong_common import markdown
from stylepong_common.command_line import require_counts
from stylepong_player.spec import ACTION_RATE_HZ
from stylepong_policy.evaluation import evaluate, style_metrics
from stylepong_policy.evaluation.strokes import DIRECTIONS, FOLLOW_THROUGH_S, save_strokes
from stylepong_policy.reports import paper_charts as charts
from stylepong_policy.reports import paper_figures as paper
from stylepong_policy.rl.export import ActorMismatchError, LoadedActor, load_actor
from stylepong_policy.training.train import actor_name
from stylepong_sim.world_spec import (
    EVALUATION_BALLS_PER_SEED,
    EVALUATION_SEEDS,
    FIRST_EVALUATION_SEED,
    SPEED_RANGES_M_S,
)

ACTOR_NAMES = ('ppo', 'amp-noaug', 'amp')
SHIPPED_FILES = {name: actor_name(name) for name in ACTOR_NAMES}  # amp-noaug: amp_noaug_actor.pt
DEFAULT_MODELS_DIR = pathlib.Path('ros2_ws/src/stylepong_policy/models')
DEFAULT_BAGS = pathlib.Path('ros2_ws/bags')
BAND_FIRST_SEED = 2000  # Table III's bands: seeds of their own, as for the shipped high-speed evaluation
BANDS = ('all', 'low', 'high')
SIM2SIM_PATTERN = 'sim2sim_*.json'
REFERENCE_NAME = 'reference_dataset.npz'


class SetupError(RuntimeError):
    """Something the command needs is missing (an actor, the reference clips); the message says what."""


@dataclass(frozen=True)
class Protocol:
    """The evaluation setting the tables state: seeds, balls per seed, first seeds and device."""

    seeds: int
    balls: int
    first_seed: int
    band_first_seed: int
    device: str

    def first_seed_of(self, band: str) -> int:
        return self.first_seed if band == 'all' else self.band_first_seed

    def setting(self, band: str) -> str:
        """The one-line setting a table or chart states."""
        lo, hi = SPEED_RANGES_M_S[band]
        return f'{self._world_and_seeds(band)}; {band} speeds {lo:.1f}-{hi:.1f} m/s'

    def bands_setting(self) -> str:
        """Table III's: the same seeds in each band."""
        return f'{self._world_and_seeds("low")} in each band'

    def _world_and_seeds(self, band: str) -> str:
        first = self.first_seed_of(band)
        seeds = f'seed {first}' if self.seeds == 1 else f'seeds {first}-{first + self.seeds - 1}'
        return (
            f'nominal batched world (no randomisation, no sensing noise), deterministic actors; '
            f'{seeds} x {self.balls} balls'
        )


# ---------------------------------------------------------------------------------------------------
# Actors and references


def parse_actor_overrides(text: str | None) -> dict[str, pathlib.Path]:
    """'ppo=a.pt,amp=b.pt' -> {'ppo': Path('a.pt'), 'amp': Path('b.pt')}."""
    if not text:
        return {}
    overrides = {}
    for part in text.split(','):
        name, sep, path = part.strip().partition('=')
        if not sep or not path:
            raise ValueError(f'--actors takes name=path pairs, got {part!r}')
        if name not in ACTOR_NAMES:
            raise ValueError(f'unknown actor name {name!r}; the tables have {", ".join(ACTOR_NAMES)}')
        overrides[name] = pathlib.Path(path)
    return overrides


def resolve_actors(overrides: dict[str, pathlib.Path], models_dir: pathlib.Path) -> dict[str, pathlib.Path]:
    """The path of each table row's actor; SetupError naming every one that is missing."""
    actors = {name: overrides.get(name, models_dir / SHIPPED_FILES[name]) for name in ACTOR_NAMES}
    missing = [f'{name}: {path}' for name, path in actors.items() if not path.is_file()]
    if missing:
        raise SetupError(
            'missing actor(s) ' + '; '.join(missing) + '. The tables need all three '
            f'({", ".join(ACTOR_NAMES)}): train and export the missing ones into {models_dir}, or '
            'pass --actors name=PATH,... to let another actor stand in.'
        )
    return actors


def load_actors(paths: dict[str, pathlib.Path]) -> dict[str, LoadedActor]:
    """Each actor loaded once, however many rows it fills; SetupError for one that does not fit."""
    by_file: dict[pathlib.Path, LoadedActor] = {}
    actors = {}
    for name, path in paths.items():
        key = path.resolve()
        if key not in by_file:
            try:
                by_file[key] = load_actor(path)
            except ActorMismatchError as err:
                raise SetupError(f'actor {name} ({path}) does not load: {err}') from err
        actors[name] = by_file[key]
    return actors


def build_reference(bags: pathlib.Path, out_path: pathlib.Path) -> pathlib.Path:
    """The DTW references: build_dataset's clips (x1, x2, x3, x5) of the demonstration bags."""
    from stylepong_policy.training import build_dataset

    report = io.StringIO()
    with contextlib.redirect_stdout(report):
        status = build_dataset.build([bags], out_path)
    if status != 0 or not out_path.is_file():
        raise SetupError(f'no reference clips from {bags} (build_dataset exit {status}):\n{report.getvalue()}')
    return out_path


# ---------------------------------------------------------------------------------------------------
# Running the evaluations


def run_all(
    actors: dict[str, LoadedActor], paths: dict[str, pathlib.Path], protocol: Protocol, log: Callable[[str], None]
) -> dict[tuple[str, str], evaluate.Evaluation]:
    """Every actor in every band (all; low and high for Table III). An actor file given for several
    names is evaluated once per band: the balls, and so the results, would be the same."""
    done: dict[tuple[pathlib.Path, str], evaluate.Evaluation] = {}
    evaluations = {}
    for band in BANDS:
        for name in ACTOR_NAMES:
            key = (paths[name].resolve(), band)
            if key not in done:
                started = time.perf_counter()
                done[key] = evaluate.evaluate_actor(
                    actors[name],
                    seeds=protocol.seeds,
                    first_seed=protocol.first_seed_of(band),
                    balls=protocol.balls,
                    speed=band,
                    device=protocol.device,
                )
                rates = [r.success_rate for r in done[key].results]
                log(
                    f'{name} {band}: success {np.mean(rates):.4f} over {sum(r.balls for r in done[key].results)} '
                    f'balls, {time.perf_counter() - started:.1f} s'
                )
            evaluations[(name, band)] = done[key]
    return evaluations


def summarise_all(
    evaluations: dict[tuple[str, str], evaluate.Evaluation],
    dataset,
    dataset_path: str | None,
    log: Callable[[str], None],
) -> dict[str, dict[str, dict]]:
    """evaluate's summary of each (actor, band); DTW for the all-speeds runs (Table II)."""
    summaries: dict[str, dict[str, dict]] = {name: {} for name in ACTOR_NAMES}
    cache: dict[tuple[int, bool], dict] = {}
    for (name, band), evaluation in evaluations.items():
        with_dtw = band == 'all'
        key = (id(evaluation), with_dtw)
        if key not in cache:
            started = time.perf_counter()
            cache[key] = evaluate.summarise(
                evaluation, dataset=dataset if with_dtw else None, dataset_path=dataset_path
            )
            if with_dtw:
                log(f'{name}: DTW of {len(evaluation.strokes)} strokes, {time.perf_counter() - started:.1f} s')
        summaries[name][band] = cache[key]
    return summaries


# ---------------------------------------------------------------------------------------------------
# Table IV


def load_sim2sim(folder: pathlib.Path) -> list[dict]:
    """Rows of Table IV from sim2sim_*.json in `folder` (written by the deployment work).

    Read from each file: a label ('simulator', 'world' or 'name'; else the file name), 'success_rate'
    (fraction), and where present 'balls_per_seed', 'seeds' (list or count), 'balls',
    'mean_successes_per_seed', 'success_rate_std', 'actor', 'command' (how it was measured). A file that
    cannot be read gives a row saying why."""
    rows = []
    for path in sorted(folder.glob(SIM2SIM_PATTERN)):
        row = {'file': path.name}
        try:
            data = json.loads(path.read_text())
            rate = float(data['success_rate'])
        except (OSError, ValueError, KeyError, TypeError) as err:
            row['error'] = f'unreadable ({type(err).__name__}: {err})'
            rows.append(row)
            continue
        seeds = data.get('seeds')
        seed_count = len(seeds) if isinstance(seeds, list) else seeds
        per_seed = data.get('balls_per_seed')
        if per_seed is None and data.get('balls') and seed_count:
            per_seed = int(data['balls']) // int(seed_count)
        mean = data.get('mean_successes_per_seed')
        if mean is None and per_seed:
            mean = rate * float(per_seed)
        row.update(
            label=str(data.get('simulator') or data.get('world') or data.get('name') or path.stem),
            success_rate=rate,
            success_rate_std=data.get('success_rate_std'),
            balls_per_seed=per_seed,
            seeds=seed_count,
            mean_successes_per_seed=mean,
            actor=data.get('actor'),
            command=data.get('command'),
        )
        rows.append(row)
    return rows


# ---------------------------------------------------------------------------------------------------
# Markdown


def band_text(band: str) -> str:
    """A speed band's range in m/s, e.g. '4.0-4.8'."""
    lo, hi = SPEED_RANGES_M_S[band]
    return f'{lo:.1f}-{hi:.1f}'


def percent(value: float | None, std: float | None = None) -> str:
    """A rate as a percentage with an optional ± std; 'n/a' for None."""
    if value is None:
        return 'n/a'
    text = f'{100.0 * value:.2f} %'
    return text + (f' ± {100.0 * std:.2f}' if std is not None else '')


def number(value: float | None, digits: int = 2) -> str:
    """A number with `digits` decimals; 'n/a' for None."""
    return 'n/a' if value is None else f'{value:.{digits}f}'


def table_one(summaries: dict[str, dict[str, dict]], protocol: Protocol) -> list[str]:
    """Table I: success rate at all speeds, the paper's and ours."""
    rows = []
    for name in ACTOR_NAMES:
        ours = summaries[name]['all']
        fig = paper.TABLE_I[name]
        rows.append(
            [
                f'{paper.PAPER_NAMES[name]} (`{name}`)',
                f'{fig.attempts} / {ours["balls_per_seed"]}',
                number(fig.mean_success),
                number(ours['mean_successes_per_seed']),
                percent(fig.success_rate),
                percent(ours['success_rate'], ours['success_rate_std']),
                percent(ours['hit_rate']),
            ]
        )
    return [
        '## Table I: success rate, all speeds',
        '',
        f'Setting: {protocol.setting("all")}.',
        '',
        *markdown.table(
            [
                'Method',
                'Attempts per seed (paper / ours)',
                'Mean success (paper)',
                'Mean success (ours)',
                'Success rate (paper)',
                'Success rate (ours, ± std over seeds)',
                'Hit rate (ours)',
            ],
            rows,
        ),
        '',
        '![Table I](table1_success.png)',
        '',
    ]


def dtw_ratio(summaries: dict[str, dict[str, dict]], direction: str) -> float | None:
    """AMP's mean DTW distance over PPO's in one direction (None when either is missing)."""
    amp = summaries['amp']['all']['dtw'][direction]['mean_rad']
    ppo = summaries['ppo']['all']['dtw'][direction]['mean_rad']
    return amp / ppo if amp is not None and ppo else None


def table_two(summaries: dict[str, dict[str, dict]], protocol: Protocol) -> list[str]:
    """Table II: DTW distance to the demonstrations per direction, the paper's and ours."""
    header = ['Method'] + [f'{d.capitalize()} ({who})' for d in DIRECTIONS for who in ('paper', 'ours')]
    rows = []
    for name in ('ppo', 'amp'):
        dtw = summaries[name]['all']['dtw']
        rows.append(
            [f'{paper.PAPER_NAMES[name]} (`{name}`)']
            + [cell for d in DIRECTIONS for cell in (number(paper.TABLE_II[name][d]), number(dtw[d]['mean_rad']))]
        )
    rows.append(
        ['ratio amp / ppo']
        + [
            cell
            for d in DIRECTIONS
            for cell in (
                number(paper.TABLE_II['amp'][d] / paper.TABLE_II['ppo'][d], 3),
                number(dtw_ratio(summaries, d), 3),
            )
        ]
    )
    extra = []
    for name in ACTOR_NAMES:
        dtw = summaries[name]['all']['dtw']
        extra.append(
            [f'`{name}`']
            + [f'{number(dtw[d]["mean_rad"])} ± {number(dtw[d]["std_rad"])}' for d in DIRECTIONS]
            + [number(dtw[d]['mean_per_path_step_rad'], 4) for d in DIRECTIONS]
            + [' / '.join(str(dtw[d]['strokes']) for d in DIRECTIONS)]
        )
    dtw_ppo = summaries['ppo']['all']['dtw']
    clip_counts = ', '.join(f'{d} {dtw_ppo[d]["reference_clips"]}' for d in DIRECTIONS)
    return [
        '## Table II: DTW distance to the demonstrations (lower is better)',
        '',
        f"Setting: {protocol.setting('all')}; every ball's stroke, labelled by the direction it came from.",
        '',
        *markdown.table(header, rows),
        '',
        'Ours in every actor, with the spread over strokes and the distance per warping-path step '
        '(rad; strokes per direction forward / leftward / rightward):',
        '',
        *markdown.table(
            ['Actor'] + [f'{d} (rad)' for d in DIRECTIONS] + [f'{d} per step' for d in DIRECTIONS] + ['strokes'], extra
        ),
        '',
        f"DTW: joint positions (rad, 6 joints) at 60 Hz from the ball's launch to {FOLLOW_THROUGH_S} s after "
        "the paddle's first contact, against every demonstration clip of the same label (all speed factors: "
        f'{clip_counts} clips), the smallest per '
        'stroke, the mean over strokes. Local cost the Euclidean distance, symmetric unweighted steps, not '
        f'normalised: `{evaluate.DTW_CALL}`. The paper does not give its DTW convention or sequence lengths, so '
        'its absolute numbers are not comparable with ours; the ratio amp / ppo is.',
        '',
        '![Table II](table2_dtw.png)',
        '',
    ]


def dtw_breakdown_section(summaries: dict[str, dict[str, dict]], protocol: Protocol) -> list[str]:
    """Where each actor's DTW distance lies: by joint and by phase of the stroke, per stroke over all directions."""
    from stylepong_description.robot_model import JOINT_NAMES

    rows = []
    for name in ACTOR_NAMES:
        dtw = summaries[name]['all']['dtw']
        strokes = sum(dtw[d]['strokes'] for d in DIRECTIONS if dtw[d]['sum_by_joint_rad'] is not None)
        if not strokes:
            continue
        per_stroke = {
            part: sum(dtw[d][key][part] for d in DIRECTIONS if dtw[d][key] is not None) / strokes
            for key, parts in (('sum_by_joint_rad', JOINT_NAMES), ('sum_by_phase_rad', style_metrics.PHASES))
            for part in parts
        }
        total = sum(per_stroke[joint] for joint in JOINT_NAMES)
        columns = (*JOINT_NAMES, *style_metrics.PHASES)
        rows.append([f'`{name}`', number(total)] + [number(per_stroke[column], 1) for column in columns])
    header = (
        ['Actor', 'DTW (rad)']
        + [f'`{joint}`' for joint in JOINT_NAMES]
        + [p.replace('_', '-') for p in style_metrics.PHASES]
    )
    offsets = summaries['ppo']['all']['dtw_by_lateral_offset']
    offset_rows = [
        [f'`{name}`']
        + [
            f'{number(entry["mean_rad"])} ({entry["strokes"]})'
            for entry in summaries[name]['all']['dtw_by_lateral_offset'].values()
        ]
        for name in ACTOR_NAMES
    ]
    return [
        '## Where the DTW distance lies (not in the paper)',
        '',
        f'Setting: {protocol.setting("all")}; the strokes and nearest clips of Table II.',
        '',
        *markdown.table(header, rows),
        '',
        'Per stroke, the mean over the strokes of all three directions (rad): each frame pair on the optimal '
        'warping path adds its Euclidean distance |d|, shared among the joints as d_k^2 / |d| and given to the '
        f"phase of its stroke frame: waiting until {style_metrics.SWING_S} s before the paddle's hit, the swing "
        'from there to the hit, the follow-through after it '
        '(`stylepong_policy.evaluation.style_metrics.cost_breakdown`). '
        'The joints add up to the DTW column, and so do the phases.',
        '',
        "By how far to the side of the paddle's home the ball arrives (|arrival y - home y|; the demonstrated "
        'hits lie within 0.18 m of it): mean DTW distance (rad) and strokes.',
        '',
        *markdown.table(['Actor'] + list(offsets), offset_rows),
        '',
    ]


@dataclass(frozen=True)
class PairedDifference:
    """amp's success rate minus amp-noaug's in one band, seed by seed (both meet the same balls)."""

    mean_points: float  # percentage points
    standard_error_points: float | None  # of the mean difference; None with one seed
    seeds: int

    def verdict(self) -> str:
        """What the speed-ups did, judged against two standard errors of the paired difference."""
        if self.standard_error_points is None:
            return 'one seed, no spread to judge it by'
        if abs(self.mean_points) <= 2.0 * self.standard_error_points:
            return 'no difference beyond two standard errors'
        return 'the speed-ups helped' if self.mean_points > 0 else 'the speed-ups hurt'


def augmentation_effect(summaries: dict[str, dict[str, dict]], band: str) -> PairedDifference:
    """What training on the x2/x3/x5 speed-ups changed (amp against amp-noaug) in one speed band."""
    with_speed_ups = np.asarray(summaries['amp'][band]['per_seed'], dtype=float)
    originals_only = np.asarray(summaries['amp-noaug'][band]['per_seed'], dtype=float)
    difference = 100.0 * (with_speed_ups - originals_only)
    seeds = len(difference)
    error = float(difference.std(ddof=1) / np.sqrt(seeds)) if seeds > 1 else None
    return PairedDifference(float(difference.mean()), error, seeds)


def augmentation_lines(summaries: dict[str, dict[str, dict]]) -> list[str]:
    """One sentence per band on the speed-ups, measured; why they do or do not help is docs/DESIGN.md's."""
    parts = []
    for band in ('low', 'high'):
        effect = augmentation_effect(summaries, band)
        error = (
            f' ± {effect.standard_error_points:.2f} standard error' if effect.standard_error_points is not None else ''
        )
        parts.append(
            f'{effect.mean_points:+.2f} points at {band} speeds{error} over {effect.seeds} seeds ({effect.verdict()})'
        )
    return [
        'What the x2/x3/x5 speed-ups changed, `amp` minus `amp-noaug` seed by seed (both meet the same '
        'balls): ' + '; '.join(parts) + '. Why they do or do not help here: docs/DESIGN.md, Known limits.',
        '',
    ]


def table_three(summaries: dict[str, dict[str, dict]], protocol: Protocol) -> list[str]:
    """Table III: success at low and high incoming speeds, the paper's and ours."""
    rows = []
    for band in ('low', 'high'):
        for name in ('amp-noaug', 'amp', 'ppo'):
            ours = summaries[name][band]
            fig = paper.TABLE_III.get((name, band))
            rows.append(
                [
                    f'{paper.PAPER_NAMES[name]} (`{name}`)' + ('' if fig else ' (not in the paper)'),
                    band,
                    f'{fig.attempts if fig else "-"} / {ours["balls_per_seed"]}',
                    number(fig.mean_success) if fig else '-',
                    number(ours['mean_successes_per_seed']),
                    percent(fig.success_rate) if fig else '-',
                    percent(ours['success_rate'], ours['success_rate_std']),
                ]
            )
    return [
        '## Table III: success at low and high incoming speeds',
        '',
        f'Setting: {protocol.bands_setting()}: low {band_text("low")}, high {band_text("high")} m/s.',
        '',
        *markdown.table(
            [
                'Method',
                'Speed',
                'Attempts per seed (paper / ours)',
                'Mean (paper)',
                'Mean (ours)',
                'Success rate (paper)',
                'Success rate (ours, ± std over seeds)',
            ],
            rows,
        ),
        '',
        *augmentation_lines(summaries),
        '![Table III](table3_speed.png)',
        '',
    ]


def smoothness_section(
    summaries: dict[str, dict[str, dict]], reference: dict[str, dict | None], protocol: Protocol
) -> list[str]:
    """The smoothness and DTW section: each actor per direction, and the demonstrations."""
    rows = []
    for name in ACTOR_NAMES:
        summary = summaries[name]['all']
        for d in DIRECTIONS:
            s = summary['smoothness'][d]
            dtw = summary['dtw'][d]
            rows.append(
                [
                    f'`{name}`',
                    d,
                    str(summary['directions'][d]['balls']),
                    number(s and s['peak_joint_speed_rad_s']),
                    number(s and s['peak_joint_acceleration_rad_s2'], 1),
                    number(s and s['mean_abs_jerk_rad_s3'], 1),
                    number(dtw['mean_rad']),
                    number(dtw['mean_per_path_step_rad'], 4),
                ]
            )
    for d in DIRECTIONS:
        s = reference[d]
        rows.append(
            [
                'demonstrations (x1)',
                d,
                '-',
                number(s and s['peak_joint_speed_rad_s']),
                number(s and s['peak_joint_acceleration_rad_s2'], 1),
                number(s and s['mean_abs_jerk_rad_s3'], 1),
                '-',
                '-',
            ]
        )
    return [
        '## Smoothness beside DTW (not in the paper)',
        '',
        f'Setting: {protocol.setting("all")}.',
        '',
        *markdown.table(
            [
                'Actor',
                'Direction',
                'Strokes',
                'Peak joint speed (rad/s)',
                'Peak joint acc. (rad/s²)',
                'Mean |jerk| (rad/s³)',
                'DTW (rad)',
                'DTW per step (rad)',
            ],
            rows,
        ),
        '',
        'Per stroke (the DTW sequences), then the mean over strokes: backward differences of the 60 Hz joint '
        'positions, qdot = Δq/Δt, qddot = Δqdot/Δt, jerk = Δqddot/Δt; peak speed and acceleration are the '
        'largest magnitude over frames and joints, the jerk the mean magnitude over frames and joints. '
        "The demonstrations' rows are the original (x1) clips, measured the same way.",
        '',
        '![Smoothness](smoothness.png)',
        '',
    ]


def directions_section(summaries: dict[str, dict[str, dict]], protocol: Protocol) -> list[str]:
    """Success per stroke direction, and how a ball's direction is decided."""
    rule = summaries['ppo']['all']['direction_rule']
    rows = []
    for name in ACTOR_NAMES:
        directions = summaries[name]['all']['directions']
        rows.append(
            [f'`{name}`'] + [f'{directions[d]["balls"]}: {percent(directions[d]["success_rate"])}' for d in DIRECTIONS]
        )
    return [
        '## Success per direction',
        '',
        f'Setting: {protocol.setting("all")}.',
        '',
        *markdown.table(['Actor'] + [f'{d} (balls: success)' for d in DIRECTIONS], rows),
        '',
        f"A ball's direction is where it crosses the paddle's home plane x = {rule['plane_x_m']} m after its "
        f"bounce, relative to the paddle's home y = {rule['paddle_home_y_m']} m (world +y is the robot's left): "
        f'leftward above +{rule["leftward_above_m"]} m, rightward below {rule["rightward_below_m"]} m, forward '
        "between (halfway between the demonstrations' hitting points; stylepong_policy.evaluation.strokes).",
        '',
    ]


def table_four(rows: list[dict], summaries: dict[str, dict[str, dict]], protocol: Protocol) -> list[str]:
    """Table IV: the paper's rows in two simulators beside ours (the batched world, then each sim2sim row)."""
    out = [
        [f'{label} (paper)', str(fig.attempts), number(fig.mean_success), percent(fig.success_rate), '-']
        for label, fig in paper.TABLE_IV.items()
    ]
    amp = summaries['amp']['all']
    out.append(
        [
            'batched world, training simulator (ours, Table I setting)',
            str(amp['balls_per_seed']),
            number(amp['mean_successes_per_seed']),
            percent(amp['success_rate'], amp['success_rate_std']),
            f'`{amp["actor"]}`',
        ]
    )
    for row in rows:
        if 'error' in row:
            out.append([f'{row["file"]}', '-', '-', row['error'], '-'])
            continue
        out.append(
            [
                f'{row["label"]} (ours, `{row["file"]}`)',
                str(row['balls_per_seed'] or 'n/a'),
                number(row['mean_successes_per_seed']),
                percent(row['success_rate'], row['success_rate_std']),
                f'`{row["actor"]}`' if row['actor'] else 'n/a',
            ]
        )
    if not rows:
        out.append(
            [
                'MuJoCo cell (ur5_sim) with the player: other simulator (ours)',
                '-',
                '-',
                'not measured',
                f'no {SIM2SIM_PATTERN} in this folder yet',
            ]
        )
    commands = [f'- `{row["file"]}`: `{row["command"]}`' for row in rows if row.get('command')]
    return [
        '## Table IV: sim2sim transfer',
        '',
        f'Rows of ours other than the batched world come from {SIM2SIM_PATTERN} files in this folder (the '
        'deployment work writes them); each states its own setting there.',
        '',
        *markdown.table(['Simulator', 'Attempts per seed', 'Mean success', 'Success rate', 'Actor'], out),
        '',
        *(['Measured with:', '', *commands, ''] if commands else []),
    ]


def figure_section(figure: dict | None, protocol: Protocol) -> list[str]:
    """The Fig. 2 section (or why it was not rendered)."""
    if figure is None:
        return ['## Fig. 2: strokes', '', 'Not rendered (--no-figure, or no ball of the chosen direction).', '']
    return [
        '## Fig. 2: strokes',
        '',
        f'The same {figure["direction"]} ball (seed {figure["seed"]}, ball {figure["ball"]}, '
        f'{figure["launch_speed_m_s"]} m/s) for PPO ({figure["outcomes"]["ppo"]}) and '
        f'AMP ({figure["outcomes"]["amp"]}), '
        f"and the {figure['reference_row']}: seven frames each, the cell's MuJoCo scene, camera "
        f'`{figure["camera"]}`. Setting: {protocol.setting("all")}.',
        '',
        '![Fig. 2](strokes.png)',
        '',
    ]


def render_markdown(summaries, reference_rows, sim2sim, figure, protocol: Protocol, context: dict) -> str:
    """The whole README.md of the tables."""
    actors = context['actors']
    stand_ins = {path for path in actors.values() if list(actors.values()).count(path) > 1}
    lines = [
        "# The paper's tables for our actors",
        '',
        'Written by `' + context['command'] + '` (do not edit: re-run it); '
        f'{context["generated"]}, {context["wall_time_s"]:.0f} s on {context["machine"]}.',
        '',
        'Actors: ' + ', '.join(f'`{name}` = `{path}`' for name, path in actors.items()) + '.',
        '',
    ]
    if stand_ins:
        lines += [
            '**Stand-in actors:** ' + ', '.join(f'`{p}`' for p in sorted(stand_ins)) + ' fills several rows, '
            "so those rows are not the paper's methods.",
            '',
        ]
    lines += table_one(summaries, protocol) + table_two(summaries, protocol)
    lines += dtw_breakdown_section(summaries, protocol) + table_three(summaries, protocol)
    lines += smoothness_section(summaries, reference_rows, protocol) + directions_section(summaries, protocol)
    lines += table_four(sim2sim, summaries, protocol) + figure_section(figure, protocol)
    lines += (
        ["## About the paper's figures", '']
        + [f'- {note}' for note in paper.INCONSISTENCIES]
        + [
            '- The paper ran IsaacGym; ours is the batched torch world of this project '
            '(stylepong_sim.batched.batched_world), '
            'with its own ball distribution, robot servo and referee, so equal numbers are not expected: the '
            'comparison is between methods under one setting.',
            '',
        ]
    )
    return '\n'.join(lines)


# ---------------------------------------------------------------------------------------------------
# Charts


def write_charts(out: pathlib.Path, summaries, reference_rows, protocol: Protocol) -> list[str]:
    """Write the charts of Tables I-III and of smoothness into `out`; returns their file names."""
    names = [f'{paper.PAPER_NAMES[n]}\n({n})' for n in ACTOR_NAMES]
    charts.success_chart(
        out / 'table1_success.png',
        names,
        [paper.TABLE_I[n].success_rate for n in ACTOR_NAMES],
        [summaries[n]['all']['success_rate'] for n in ACTOR_NAMES],
        [summaries[n]['all']['success_rate_std'] for n in ACTOR_NAMES],
        'Table I: success rate, all speeds',
        protocol.setting('all'),
    )
    charts.dtw_chart(
        out / 'table2_dtw.png',
        [paper.TABLE_II['amp'][d] / paper.TABLE_II['ppo'][d] for d in DIRECTIONS],
        [dtw_ratio(summaries, d) for d in DIRECTIONS],
        {n: [summaries[n]['all']['dtw'][d]['mean_rad'] for d in DIRECTIONS] for n in ACTOR_NAMES},
        'Table II: ' + protocol.setting('all'),
    )
    pairs = [(n, b) for b in ('low', 'high') for n in ('amp-noaug', 'amp', 'ppo')]
    charts.success_chart(
        out / 'table3_speed.png',
        [f'{n}\n{b}' for n, b in pairs],
        [paper.TABLE_III[p].success_rate if p in paper.TABLE_III else None for p in pairs],
        [summaries[n][b]['success_rate'] for n, b in pairs],
        [summaries[n][b]['success_rate_std'] for n, b in pairs],
        'Table III: low (4.0-4.8) and high (5.8-6.6 m/s) incoming speeds',
        protocol.bands_setting(),
    )
    charts.smoothness_chart(
        out / 'smoothness.png',
        {n: summaries[n]['all']['smoothness'] for n in ACTOR_NAMES},
        reference_rows,
        'Smoothness per direction: ' + protocol.setting('all'),
    )
    return ['table1_success.png', 'table2_dtw.png', 'table3_speed.png', 'smoothness.png']


# ---------------------------------------------------------------------------------------------------
# Command line


def parse_args(argv: list[str] | None) -> argparse.Namespace:
    """The command line of paper_tables."""
    parser = argparse.ArgumentParser(prog='paper_tables', description=__doc__.split('\n\n')[0])
    parser.add_argument('--out', type=pathlib.Path, required=True, help='folder for README.md, charts, JSON')
    parser.add_argument(
        '--actors', help=f'name=path,... for any of {", ".join(ACTOR_NAMES)} (default: the shipped ones)'
    )
    parser.add_argument(
        '--models-dir', type=pathlib.Path, default=DEFAULT_MODELS_DIR, help='where the shipped actors are'
    )
    parser.add_argument('--seeds', type=int, default=EVALUATION_SEEDS, help='seeds per table')
    parser.add_argument('--balls', type=int, default=EVALUATION_BALLS_PER_SEED, help='balls per seed')
    parser.add_argument('--first-seed', type=int, default=FIRST_EVALUATION_SEED, help='first seed of Tables I, II')
    parser.add_argument('--band-first-seed', type=int, default=BAND_FIRST_SEED, help='first seed of Table III')
    source = parser.add_mutually_exclusive_group()
    source.add_argument('--dataset', type=pathlib.Path, help='reference dataset (.npz from build_dataset) for DTW')
    source.add_argument('--bags', type=pathlib.Path, default=DEFAULT_BAGS, help='demonstration bags to build it from')
    parser.add_argument('--no-figure', action='store_true', help='skip Fig. 2 (rendering)')
    parser.add_argument('--figure-direction', choices=DIRECTIONS, default='forward', help='the ball of Fig. 2')
    parser.add_argument(
        '--camera',
        default='figure',
        help="Fig. 2's camera: figure (close to the robot), or the scene's overview or robot_view",
    )
    parser.add_argument(
        '--save-strokes', action='store_true', help='also write every stroke (strokes_<actor>_<band>.npz)'
    )
    parser.add_argument('--device', default='cpu', help='torch device of the world')
    parser.add_argument('--num-threads', type=int, default=2, help='torch CPU threads')
    args = parser.parse_args(argv)
    require_counts(parser, args, ('seeds', 'balls', 'num_threads'))
    try:
        args.actor_overrides = parse_actor_overrides(args.actors)
    except ValueError as err:
        parser.error(str(err))
    return args


def command_line(args: argparse.Namespace) -> str:
    """The command as a person would type it again, with paths as given (none absolute)."""
    parts = ['ros2 run stylepong_policy paper_tables', f'--out {evaluate.portable_path(args.out)}']
    if args.actor_overrides:
        overrides = ','.join(f'{n}={evaluate.portable_path(p)}' for n, p in args.actor_overrides.items())
        parts.append(f'--actors {overrides}')
    for flag, value, default in (
        ('--seeds', args.seeds, EVALUATION_SEEDS),
        ('--balls', args.balls, EVALUATION_BALLS_PER_SEED),
        ('--first-seed', args.first_seed, FIRST_EVALUATION_SEED),
        ('--band-first-seed', args.band_first_seed, BAND_FIRST_SEED),
    ):
        if value != default:
            parts.append(f'{flag} {value}')
    if args.dataset is not None:
        parts.append(f'--dataset {evaluate.portable_path(args.dataset)}')
    if args.no_figure:
        parts.append('--no-figure')
    return ' '.join(parts)


def main(argv: list[str] | None = None) -> int:
    """Entry point of the paper_tables executable."""
    args = parse_args(argv)
    started = time.perf_counter()
    torch.set_num_threads(args.num_threads)

    def log(message: str) -> None:
        print(f'[paper_tables {time.perf_counter() - started:6.1f} s] {message}', flush=True)

    protocol = Protocol(
        seeds=args.seeds,
        balls=args.balls,
        first_seed=args.first_seed,
        band_first_seed=args.band_first_seed,
        device=args.device,
    )
    out = args.out
    if not args.no_figure:
        from stylepong_policy.reports.stroke_figure import CAMERAS

        if args.camera not in CAMERAS:
            print(f'paper_tables: unknown camera {args.camera!r}; choose one of {", ".join(CAMERAS)}', file=sys.stderr)
            return 2
    try:
        paths = resolve_actors(args.actor_overrides, args.models_dir)
        actors = load_actors(paths)
        out.mkdir(parents=True, exist_ok=True)
        dataset_path = args.dataset if args.dataset is not None else build_reference(args.bags, out / REFERENCE_NAME)
        dataset = evaluate.load_reference(dataset_path)
    except (SetupError, OSError, KeyError, ValueError) as err:
        print(f'paper_tables: {err}', file=sys.stderr)
        return 2
    log(f'reference clips: {dataset.num_clips} from {evaluate.portable_path(dataset_path)}')

    evaluations = run_all(actors, paths, protocol, log)
    summaries = summarise_all(evaluations, dataset, evaluate.portable_path(dataset_path), log)
    reference_rows = style_metrics.reference_smoothness(dataset, DIRECTIONS, speed_factor=1)
    if args.save_strokes:
        for (name, band), evaluation in evaluations.items():
            save_strokes(
                out / f'strokes_{name}_{band}.npz',
                evaluation.strokes,
                rate_hz=ACTION_RATE_HZ,
                joint_names=dataset.joint_names,
                actor=evaluate.portable_path(paths[name]),
                speed=band,
            )
        log('strokes written')
    figure = None
    if not args.no_figure:
        figure = _figure(out, evaluations, dataset, args, protocol)
        log('Fig. 2 rendered' if figure else f'Fig. 2: no {args.figure_direction} ball, not rendered')
    images = write_charts(out, summaries, reference_rows, protocol)
    sim2sim = load_sim2sim(out)
    wall_time_s = time.perf_counter() - started
    context = {
        'command': command_line(args),
        'actors': {n: evaluate.portable_path(p) for n, p in paths.items()},
        'generated': datetime.date.today().isoformat(),
        'wall_time_s': wall_time_s,
        'machine': f'{os.cpu_count()} CPU cores, {args.num_threads} torch threads, device {args.device}',
    }
    (out / 'README.md').write_text(render_markdown(summaries, reference_rows, sim2sim, figure, protocol, context))
    record = {
        'command': context['command'],
        'actors': context['actors'],
        'protocol': protocol.__dict__,
        'settings': {band: protocol.setting(band) for band in BANDS},
        'reference_dataset': evaluate.portable_path(dataset_path),
        'evaluations': summaries,
        'reference_smoothness_x1': reference_rows,
        'sim2sim': sim2sim,
        'figure': figure,
        'charts': images,
        'wall_time_s': round(wall_time_s, 1),
    }
    (out / 'paper_tables.json').write_text(json.dumps(record, indent=2) + '\n')
    log(f'wrote {evaluate.portable_path(out / "README.md")} and the charts; {wall_time_s:.0f} s in all')
    return 0


def _figure(out: pathlib.Path, evaluations, dataset, args: argparse.Namespace, protocol: Protocol) -> dict | None:
    from stylepong_policy.reports.stroke_figure import stroke_figure

    return stroke_figure(
        out / 'strokes.png',
        evaluations[('ppo', 'all')].strokes,
        evaluations[('amp', 'all')].strokes,
        dataset,
        ACTION_RATE_HZ,
        direction=args.figure_direction,
        camera=args.camera,
        setting=protocol.setting('all') + '.',
    )


if __name__ == '__main__':
    sys.exit(main())
