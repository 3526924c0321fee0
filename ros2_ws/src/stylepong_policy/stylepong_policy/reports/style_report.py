"""RUN/report.md of a learned style: whether it met its targets (TARGET_RATIOS, TARGET_SUCCESS_RATE) and
the distance left, success, DTW to the demonstrations beside PPO's and the shipped style actor's, the blade
at contact, smoothness, and the new actor's stroke beside its nearest demonstration (no rclpy).

What it reads, under RUN/EVAL_DIR (`eval_files(run_dir, actor)` gives the paths), for each of ACTORS
('style': the new actor, 'ppo', 'shipped': the shipped style actor):
  <actor>_all.json      what `evaluate --speed all --dtw DATASET --json` writes (evaluate.summarise with
                        the run's dataset), required for every actor;
  <actor>_high.json     the same at `--speed high`; required for 'style', shown for the others when there;
  <actor>_strokes.npz   `--save-strokes` of the all-speeds evaluation (strokes.save_strokes), every actor.
All three actors are meant to meet the same balls (same seeds and balls per seed); the report says so
when they did not. Plus the run's dataset .npz (the demonstrations the DTW was measured against), the
wall time of each stage and the chosen checkpoints, printed as given.

What it writes, in RUN: report.md, report.json (the figures in it) and the PNGs named by the *_PNG
constants: success, DTW and ratios, smoothness, and per demonstrated direction a strip of frames (PPO's
stroke, the new actor's on the same ball, the demonstration nearest to the new actor's: the paper's
Fig. 2 laid out by stroke_figure) and the joint angles of that stroke beside that demonstration.
A strip needs an OpenGL context (EGL headless); without one the report says why it has none.

write_report_of writes the same from evaluations in hand into any folder: style_confusion's, which
evaluated every actor already (all speeds only: no high-speed success then).
"""

from __future__ import annotations

import datetime
import json
import os
import pathlib
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from stylepong_common import markdown
from stylepong_policy import png
from stylepong_policy.evaluation import contacts, style_metrics
from stylepong_policy.evaluation.strokes import DIRECTIONS, NO_FRAME, Stroke, load_strokes

ACTORS = ('style', 'ppo', 'shipped')
ACTOR_TITLES = {'style': 'new style actor', 'ppo': 'PPO (no style)', 'shipped': 'shipped style actor'}
DEMONSTRATIONS = 'demonstrations'  # the key of the demonstrations' row among the actors' (blade_at_contact)
EVAL_DIR = 'eval'
ALL_SPEEDS_JSON = '{actor}_all.json'
HIGH_SPEEDS_JSON = '{actor}_high.json'
STROKES_NPZ = '{actor}_strokes.npz'
REPORT_MD = 'report.md'
REPORT_JSON = 'report.json'
SUCCESS_PNG = 'report_success.png'
DTW_PNG = 'report_dtw.png'
SMOOTHNESS_PNG = 'report_smoothness.png'
STRIP_PNG = 'report_strip_{direction}.png'
JOINTS_PNG = 'report_joints_{direction}.png'
OVERALL = 'overall'
COLUMNS = (*DIRECTIONS, OVERALL)  # the columns of the DTW figures: each direction, then all strokes
# The ratios of mean DTW distances the report gives: name -> (numerator's actor, denominator's actor).
RATIO_PAIRS = {
    'style / ppo': ('style', 'ppo'),
    'style / shipped': ('style', 'shipped'),
    'shipped / ppo': ('shipped', 'ppo'),
}
# The targets learn_style is held to: in every column (each direction and overall) the new actor's mean DTW
# distance to the demonstrations at most these fractions of PPO's and of the shipped style actor's on the
# same balls, and at least TARGET_SUCCESS_RATE of the balls returned at all speeds.
TARGET_RATIOS = {'style / ppo': 0.40, 'style / shipped': 0.65}
TARGET_SUCCESS_RATE = 0.90


@dataclass(frozen=True)
class EvalFiles:
    """The evaluation files of one actor under RUN/EVAL_DIR."""

    all_speeds_json: pathlib.Path
    high_speeds_json: pathlib.Path
    strokes_npz: pathlib.Path


def eval_files(run_dir: str | os.PathLike, actor: str) -> EvalFiles:
    """Where the evaluation files of `actor` (one of ACTORS) belong in a run."""
    folder = pathlib.Path(run_dir) / EVAL_DIR
    return EvalFiles(
        all_speeds_json=folder / ALL_SPEEDS_JSON.format(actor=actor),
        high_speeds_json=folder / HIGH_SPEEDS_JSON.format(actor=actor),
        strokes_npz=folder / STROKES_NPZ.format(actor=actor),
    )


@dataclass
class ActorResults:
    """One actor's evaluation: the all-speeds summary (with DTW), the high-speeds one, its strokes."""

    name: str
    all_speeds: dict
    high_speeds: dict | None
    strokes: list[Stroke]
    rate_hz: float  # the strokes' frame rate


def load_actor_results(run_dir: str | os.PathLike, actor: str, *, high_required: bool) -> ActorResults:
    """Read an actor's files (eval_files); ValueError naming the file that is missing or lacks DTW."""
    files = eval_files(run_dir, actor)
    for path in (files.all_speeds_json, files.strokes_npz) + ((files.high_speeds_json,) if high_required else ()):
        if not path.is_file():
            raise ValueError(f'{path}: missing (evaluate --json / --save-strokes writes it)')
    all_speeds = json.loads(files.all_speeds_json.read_text())
    if not isinstance(all_speeds.get('dtw'), dict):
        raise ValueError(f'{files.all_speeds_json}: no DTW in it (evaluate it with --dtw DATASET)')
    high = json.loads(files.high_speeds_json.read_text()) if files.high_speeds_json.is_file() else None
    stroke_file = load_strokes(files.strokes_npz)
    return ActorResults(
        name=actor, all_speeds=all_speeds, high_speeds=high, strokes=stroke_file.strokes, rate_hz=stroke_file.rate_hz
    )


# ---------------------------------------------------------------------------------------------------
# Figures from the summaries


def overall_dtw_rad(dtw: Mapping[str, dict]) -> float | None:
    """Mean DTW over every stroke that had a demonstration of its label (each direction's mean weighted
    by its strokes); None when no direction had one."""
    weighted = [
        (entry['mean_rad'], entry['strokes'])
        for entry in dtw.values()
        if entry.get('mean_rad') is not None and entry.get('strokes')
    ]
    total = sum(count for _, count in weighted)
    return sum(mean * count for mean, count in weighted) / total if total else None


def dtw_by_direction(summary: dict) -> dict[str, float | None]:
    """Mean DTW (rad) per direction and OVERALL of an all-speeds summary."""
    table = {d: summary['dtw'][d]['mean_rad'] for d in DIRECTIONS}
    table[OVERALL] = overall_dtw_rad(summary['dtw'])
    return table


def dtw_by_phase(summary: dict, directions: Sequence[str] = DIRECTIONS) -> dict[str, float | None]:
    """Mean DTW per stroke (rad) in each phase of the stroke (style_metrics.PHASES: waiting for the ball,
    the swing's last SWING_S before the hit, the follow-through), over the strokes from `directions` with
    clips of their label: where a stroke's distance from the demonstrations lies."""
    entries = [summary['dtw'][d] for d in directions if summary['dtw'][d].get('sum_by_phase_rad')]
    strokes = sum(entry['strokes'] for entry in entries)
    return {
        phase: (sum(entry['sum_by_phase_rad'][phase] for entry in entries) / strokes if strokes else None)
        for phase in style_metrics.PHASES
    }


def ratio(numerator: float | None, denominator: float | None) -> float | None:
    """numerator / denominator, None when either is missing or the denominator is zero."""
    return numerator / denominator if numerator is not None and denominator else None


def phases_by_column(summary: dict) -> dict[str, dict[str, float | None]]:
    """dtw_by_phase of each direction's strokes alone and of every stroke (OVERALL)."""
    return {c: dtw_by_phase(summary, DIRECTIONS if c == OVERALL else (c,)) for c in COLUMNS}


def dtw_ratios(distances: Mapping[str, Mapping[str, float | None]]) -> dict[str, dict[str, float | None]]:
    """The new actor's DTW over PPO's and over the shipped actor's, and the shipped over PPO's, per column."""
    return {name: {c: ratio(distances[a][c], distances[b][c]) for c in COLUMNS} for name, (a, b) in RATIO_PAIRS.items()}


def target_checks(distances: Mapping[str, Mapping[str, float | None]], success_rate: float) -> dict:
    """The report's figures against the targets (TARGET_RATIOS, TARGET_SUCCESS_RATE).

    distances: mean DTW (rad) per actor and column (dtw_by_direction); success_rate: the new actor's at all
    speeds. Per column and ratio of TARGET_RATIOS: the ratio, its target, met (None: not measured, a
    distance missing, which is no pass) and, when missed, left_rad: the new actor's mean DTW minus target x
    the reference's, how much nearer its strokes must come. Then the success rate against its target."""
    ratios = dtw_ratios(distances)
    dtw: dict[str, dict[str, dict]] = {}
    for column in COLUMNS:
        dtw[column] = {}
        for name, target in TARGET_RATIOS.items():
            value = ratios[name][column]
            met = None if value is None else bool(value <= target)
            reference = distances[RATIO_PAIRS[name][1]][column]
            left = distances['style'][column] - target * reference if met is False else None
            dtw[column][name] = {'ratio': value, 'target': target, 'met': met, 'left_rad': left}
    success = {'rate': success_rate, 'target': TARGET_SUCCESS_RATE, 'met': bool(success_rate >= TARGET_SUCCESS_RATE)}
    return {'dtw': dtw, 'success': success}


def excess_by_phase(
    style: Mapping[str, float | None], reference: Mapping[str, float | None], target: float
) -> dict[str, float] | None:
    """Per phase (style_metrics.PHASES), the new actor's mean DTW minus target x the reference's (rad): the
    phases' parts of the distance left (they add up to it). None when a phase is not measured."""
    if any(style[p] is None or reference[p] is None for p in style_metrics.PHASES):
        return None
    return {p: style[p] - target * reference[p] for p in style_metrics.PHASES}


def largest_excess(excess: Mapping[str, float]) -> dict:
    """The phase with the largest excess and its share of the phases' excesses over their targets (a phase
    within its target is left out of the whole, so that shares stay within 100 %)."""
    phase = max(excess, key=excess.get)
    over = sum(value for value in excess.values() if value > 0)
    return {'phase': phase, 'share': excess[phase] / over if over > 0 else None}


def targets_record(
    distances: Mapping[str, Mapping[str, float | None]],
    phases: Mapping[str, Mapping[str, Mapping[str, float | None]]],
    success_rate: float,
    blades: Mapping[str, Mapping[str, dict | None]],
) -> dict:
    """target_checks, with where the distance left lies: each missed target's excess by phase (phases: per
    actor, phases_by_column) and its largest, and per direction whose distance misses a target (every
    direction when OVERALL does) the new actor's blade at contact minus the demonstrations' (blades: the
    report's mean_blades). Then how many targets were met, missed and not measured."""
    checks = target_checks(distances, success_rate)
    for column, by_ratio in checks['dtw'].items():
        for name, check in by_ratio.items():
            reference = phases[RATIO_PAIRS[name][1]][column]
            missed = check['met'] is False  # met or not measured: no distance left to place
            excess = excess_by_phase(phases['style'][column], reference, check['target']) if missed else None
            check['excess_by_phase_rad'] = excess
            check['lies_in'] = None if excess is None else largest_excess(excess)
    missing = [c for c, by_ratio in checks['dtw'].items() if any(x['met'] is False for x in by_ratio.values())]
    directions = DIRECTIONS if OVERALL in missing else [d for d in DIRECTIONS if d in missing]
    checks['blade_minus_demonstrations'] = {
        d: contacts.blade_difference(blades['style'][d], blades[DEMONSTRATIONS][d]) for d in directions
    }
    verdicts = [x['met'] for by_ratio in checks['dtw'].values() for x in by_ratio.values()]
    verdicts.append(checks['success']['met'])
    checks['count'] = {
        'targets': len(verdicts),
        'met': verdicts.count(True),
        'missed': verdicts.count(False),
        'not_measured': verdicts.count(None),
    }
    checks['verdict'] = targets_verdict(checks['count'])
    return checks


def targets_verdict(count: Mapping[str, int]) -> str:
    """One line: every target met, or how many were missed (and not measured: no pass either)."""
    if count['met'] == count['targets']:
        return 'The new style actor met every target.'
    told = f'missed {count["missed"]}' if count['missed'] else f'met {count["met"]}'
    unmeasured = f' ({count["not_measured"]} not measured: no DTW there)' if count['not_measured'] else ''
    return f'The new style actor {told} of {count["targets"]} targets{unmeasured}.'


def setting_text(summary: dict) -> str:
    """The evaluation setting of a summary, in one line (world, seeds, balls, speeds)."""
    seeds = summary['seeds']
    seed_text = f'seed {seeds[0]}' if len(seeds) == 1 else f'seeds {seeds[0]}-{seeds[-1]}'
    return f'{summary["world"]}; {seed_text} x {summary["balls_per_seed"]} balls; {summary["speed"]} speeds'


# ---------------------------------------------------------------------------------------------------
# Charts


def _grouped_bars(ax, groups: Sequence[str], series: Mapping[str, Sequence[float | None]], digits: int) -> None:
    """Bars of each series side by side in every group, each labelled with its value (a missing one: n/a)."""
    x = np.arange(len(groups))
    width = 0.8 / max(len(series), 1)
    for k, (name, values) in enumerate(series.items()):
        offsets = x - 0.4 + width * (k + 0.5)
        bars = ax.bar(offsets, [np.nan if v is None else v for v in values], width, label=name)
        for bar, offset, value in zip(bars, offsets, values):
            text = 'n/a' if value is None else f'{value:.{digits}f}'
            ax.annotate(text, (offset, 0 if value is None else bar.get_height()), ha='center', va='bottom', fontsize=7)
    ax.set_xticks(x, groups)
    ax.legend(fontsize=8)


def success_chart(path: pathlib.Path, results: Mapping[str, ActorResults]) -> pathlib.Path:
    """Success rate (%) of each actor at all speeds and at high speeds."""
    plt = png.headless_pyplot()
    figure, ax = plt.subplots(figsize=(7, 4.2))
    series = {
        ACTOR_TITLES[name]: [
            100 * r.all_speeds['success_rate'],
            None if r.high_speeds is None else 100 * r.high_speeds['success_rate'],
        ]
        for name, r in results.items()
    }
    _grouped_bars(ax, ['all speeds', 'high speeds'], series, digits=1)
    ax.set_ylabel('balls returned (%)')
    ax.set_ylim(0, 110)
    ax.set_title(f'Success\n{setting_text(results["style"].all_speeds)}', fontsize=8)
    return png.save_chart(figure, path)


def dtw_chart(
    path: pathlib.Path,
    distances: Mapping[str, Mapping[str, float | None]],
    ratios: Mapping[str, Mapping[str, float | None]],
    setting: str,
) -> pathlib.Path:
    """Left: mean DTW per direction of each actor; right: the ratios."""
    plt = png.headless_pyplot()
    figure, (left, right) = plt.subplots(1, 2, figsize=(12, 4.4))
    _grouped_bars(left, COLUMNS, {ACTOR_TITLES[a]: [distances[a][c] for c in COLUMNS] for a in distances}, digits=1)
    left.set_ylabel('mean DTW to the demonstrations (rad)')
    left.set_title('DTW distance (lower: nearer the demonstrations)', fontsize=9)
    _grouped_bars(right, COLUMNS, {name: [values[c] for c in COLUMNS] for name, values in ratios.items()}, digits=2)
    right.axhline(1.0, color='k', linewidth=0.6)
    right.set_ylabel('ratio of mean DTW distances')
    right.set_title('ratios (below 1: the first nearer the demonstrations)', fontsize=9)
    figure.suptitle(setting, fontsize=8)
    return png.save_chart(figure, path)


def joints_chart(
    path: pathlib.Path, stroke: Stroke, clip_q_rad: np.ndarray, rate_hz: float, title: str
) -> pathlib.Path:
    """Each joint's angle over the stroke and over the demonstration clip, their hits at time 0."""
    from stylepong_description.robot_model import JOINT_NAMES
    from stylepong_policy.training.dataset import hit_frame

    plt = png.headless_pyplot()
    figure, axes = plt.subplots(2, 3, figsize=(12, 5.5), sharex=True)
    stroke_q = stroke.joint_positions_rad
    stroke_hit = stroke.hit_frame if stroke.hit_frame != NO_FRAME else len(stroke_q) - 1
    clip_hit = hit_frame(np.gradient(clip_q_rad, 1.0 / rate_hz, axis=0))
    stroke_t = (np.arange(len(stroke_q)) - stroke_hit) / rate_hz
    clip_t = (np.arange(len(clip_q_rad)) - clip_hit) / rate_hz
    for j, ax in enumerate(axes.flat):
        ax.plot(stroke_t, stroke_q[:, j], label='new style actor')
        ax.plot(clip_t, clip_q_rad[:, j], '--', label='demonstration')
        ax.set_title(JOINT_NAMES[j], fontsize=8)
        ax.axvline(0.0, color='k', linewidth=0.5)
    for ax in axes[1]:
        ax.set_xlabel('time from the hit (s)')
    axes[0][0].set_ylabel('rad')
    axes[1][0].set_ylabel('rad')
    axes[0][0].legend(fontsize=7)
    figure.suptitle(title, fontsize=8)
    return png.save_chart(figure, path)


# ---------------------------------------------------------------------------------------------------
# Strips of frames (Fig. 2 style)


def strip_for_direction(
    run_dir: pathlib.Path, results: Mapping[str, ActorResults], dataset, direction: str, rate_hz: float, render: bool
) -> dict | None:
    """PPO's and the new actor's strokes on one ball of `direction` and the demonstration nearest the new
    actor's: a strip of frames (when `render`) and a joint-angle chart. None when no ball came from there."""
    from stylepong_policy.reports import stroke_figure as fig

    key = fig.choose_ball(results['ppo'].strokes, results['style'].strokes, direction)
    if key is None:
        return None
    ppo = next(s for s in results['ppo'].strokes if (s.seed, s.ball) == key)
    ours = next(s for s in results['style'].strokes if (s.seed, s.ball) == key)
    rows = [
        fig.policy_row(f'PPO ({ppo.outcome})', ppo, rate_hz),
        fig.policy_row(f'new style actor ({ours.outcome})', ours, rate_hz),
        fig.reference_row(f'demonstration, {direction}', dataset, direction, ours),
    ]
    originals = style_metrics.reference_clips(dataset, direction, speed_factors=[1])
    match = style_metrics.nearest_reference(ours.joint_positions_rad, originals)
    entry = {
        'direction': direction,
        'seed': key[0],
        'ball': key[1],
        'launch_speed_m_s': round(ours.launch_speed_m_s, 3),
        'outcomes': {'ppo': ppo.outcome, 'style': ours.outcome},
        'demonstration_clip': match.clip,
        'demonstration_source': str(dataset.source[match.clip]),
        'dtw_to_it_rad': round(match.distance, 2),
        'strip': None,
        'strip_missing': None,
    }
    title = (
        f'a {direction} ball (seed {key[0]}, ball {key[1]}, {ours.launch_speed_m_s:.2f} m/s): the new style '
        f'actor against its nearest original demonstration, clip {match.clip} (DTW {match.distance:.1f} rad)'
    )
    entry['joints'] = joints_chart(
        run_dir / JOINTS_PNG.format(direction=direction), ours, dataset.clip(match.clip).q, rate_hz, title
    ).name
    if render:
        path = run_dir / STRIP_PNG.format(direction=direction)
        try:
            fig.save_grid(
                path,
                rows,
                fig.render_rows(rows),
                f"{title}; policy frames from the paddle's contact, clip frames from its start",
            )
            entry['strip'] = path.name
        except Exception as error:  # noqa: BLE001  no OpenGL context: the report says so instead of a strip
            entry['strip_missing'] = f'not rendered ({type(error).__name__}: {str(error).splitlines()[0][:160]})'
    else:
        entry['strip_missing'] = 'not rendered (rendering turned off)'
    return entry


# ---------------------------------------------------------------------------------------------------
# Markdown


def _number(value: float | None, digits: int = 2) -> str:
    return 'n/a' if value is None else f'{value:.{digits}f}'


def _percent(value: float | None, std: float | None = None) -> str:
    if value is None:
        return 'n/a'
    return f'{100 * value:.1f} %' + (f' ± {100 * std:.1f}' if std is not None else '')


def _same_balls(results: Mapping[str, ActorResults]) -> bool:
    keys = {(tuple(r.all_speeds['seeds']), r.all_speeds['balls_per_seed']) for r in results.values()}
    return len(keys) == 1


VERDICT_WORDS = {True: 'met', False: 'missed', None: 'not measured'}  # a target's `met`, in words


def targets_section(checks: Mapping) -> list[str]:
    """The verdict, each column against the DTW targets with the distance left and where it lies, the blade
    at contact where a direction misses, and success (checks: targets_record)."""
    rows = []
    for column, by_ratio in checks['dtw'].items():
        missed = {name: x for name, x in by_ratio.items() if x['met'] is False}
        # The target a column misses by most: meeting it meets the column's other target too.
        worst = max(missed, key=lambda name: missed[name]['left_rad'], default=None)
        left = '' if worst is None else f'{missed[worst]["left_rad"]:.2f} ({worst})'
        lies_in = missed[worst]['lies_in'] if worst else None
        where = f'{lies_in["phase"].replace("_", "-")}, {100 * lies_in["share"]:.0f} % of the excess' if lies_in else ''
        ratios = (f'{_number(x["ratio"], 3)}, {VERDICT_WORDS[x["met"]]}' for x in by_ratio.values())
        rows.append([column, *ratios, left, where])
    header = ['Column', *(f'ratio {name} (target <= {target:.2f})' for name, target in TARGET_RATIOS.items())]
    blades = [
        f'{d}: {"no contact to compare" if diff is None else contacts.difference_text(diff)}'
        for d, diff in checks['blade_minus_demonstrations'].items()
    ]
    success = checks['success']
    lines = [
        '## Targets',
        '',
        checks['verdict'],
        '',
        "The targets learn_style is held to: in each direction and overall, the new actor's mean DTW distance "
        "to the demonstrations within the given fraction of PPO's and of the shipped style actor's. Distance "
        'left: how much nearer (rad of mean DTW) its strokes must come to meet the target a column misses by '
        "most; where it lies: the phase with the largest share of that excess (the new actor's mean per "
        "phase minus target x the reference's).",
        '',
        *markdown.table([*header, 'Distance left (rad)', 'Where it lies'], rows),
        '',
    ]
    if blades:
        lines += [f"At contact, the new actor's blade minus the demonstrations': {'; '.join(blades)}.", '']
    return lines + [
        f'Success at all speeds: {_percent(success["rate"])} of the balls returned, target at least '
        f'{_percent(success["target"])}: {VERDICT_WORDS[success["met"]]}.',
        '',
    ]


def success_section(results: Mapping[str, ActorResults]) -> list[str]:
    """Success at all and at high speeds, each actor."""
    rows = []
    for name, r in results.items():
        high = r.high_speeds
        rows.append(
            [
                ACTOR_TITLES[name],
                f'`{r.all_speeds["actor"]}`',
                _percent(r.all_speeds['success_rate'], r.all_speeds['success_rate_std']),
                'not evaluated' if high is None else _percent(high['success_rate'], high['success_rate_std']),
                _percent(r.all_speeds['hit_rate']),
            ]
        )
    style = results['style']
    lines = ['## Success', '', f'All speeds: {setting_text(style.all_speeds)}.']
    if style.high_speeds is not None:
        lines.append(f'High speeds: {setting_text(style.high_speeds)}.')
    header = ['Actor', 'File', 'All speeds (± std over seeds)', 'High speeds', 'Hit rate']
    return [*lines, '', *markdown.table(header, rows), '', f'![success]({SUCCESS_PNG})', '']


def dtw_section(
    results: Mapping[str, ActorResults], distances, ratios, phases, dataset_name: str, clips: Mapping[str, int]
) -> list[str]:
    """DTW per direction of each actor, the ratios, and where each actor's distance lies by phase."""
    rows = [
        [ACTOR_TITLES[name]]
        + [_number(distances[name][c]) for c in COLUMNS]
        + [' / '.join(str(r.all_speeds['dtw'][d]['strokes']) for d in DIRECTIONS)]
        for name, r in results.items()
    ]
    rows += [[f'ratio {name}'] + [_number(values[c], 3) for c in COLUMNS] + [''] for name, values in ratios.items()]
    missing = [d for d in DIRECTIONS if not clips.get(d)]
    lines = [
        '## DTW to the demonstrations',
        '',
        f"Mean over strokes of each stroke's DTW distance (rad) to the nearest clip of its own label in "
        f'`{dataset_name}` (all speed factors), by the direction the ball came from; `{OVERALL}` is the mean '
        'over every stroke that had clips of its label. Demonstration clips per label (originals): '
        + ', '.join(f'{d} {clips.get(d, 0)}' for d in DIRECTIONS)
        + '.',
        '',
        *markdown.table(['Actor', *COLUMNS, 'strokes (fwd / left / right)'], rows),
        '',
    ]
    if missing:
        lines += [f'No demonstration labelled {", ".join(missing)}: those strokes have no DTW here.', '']
    lines += [
        f"Where the distance lies: the mean per stroke split by the stroke's phase (waiting from the "
        f'launch to {style_metrics.SWING_S:g} s before the hit, the swing up to it, the follow-through '
        'after it), rad.',
        '',
        *markdown.table(
            ['Actor', *(p.replace('_', '-') for p in style_metrics.PHASES)],
            [[ACTOR_TITLES[name]] + [_number(phases[name][p]) for p in style_metrics.PHASES] for name in results],
        ),
        '',
    ]
    return [*lines, f'![DTW]({DTW_PNG})', '']


def contact_section(blades: Mapping[str, Mapping[str, dict | None]]) -> list[str]:
    """How each actor's blade meets its balls beside how the demonstrations meet theirs."""
    titles = {**ACTOR_TITLES, DEMONSTRATIONS: DEMONSTRATIONS}
    rows = {titles[name]: by_direction for name, by_direction in blades.items()}
    return [
        '## The blade at contact',
        '',
        'Where a stroke meets the ball sets much of its distance from the '
        'demonstrations: every frame around the contact pays for the pose that puts the blade there. '
        + contacts.TABLE_NOTE,
        '',
        *markdown.table(*contacts.contact_table(rows)),
        '',
    ]


def smoothness_section(results: Mapping[str, ActorResults], reference: Mapping[str, dict | None]) -> list[str]:
    """Peak joint speed and acceleration and mean |jerk| of each actor's strokes, and of the demonstrations."""
    measures = ('peak_joint_speed_rad_s', 'peak_joint_acceleration_rad_s2', 'mean_abs_jerk_rad_s3')
    rows = []
    for name, r in results.items():
        for d in (*DIRECTIONS, 'all'):
            values = r.all_speeds['smoothness'].get(d)
            rows.append([ACTOR_TITLES[name], d] + [_number(values and values[m], 1) for m in measures])
    for d in DIRECTIONS:
        values = reference.get(d)
        rows.append(['demonstrations (x1)', d] + [_number(values and values[m], 1) for m in measures])
    return [
        '## Smoothness',
        '',
        'Per stroke from the 60 Hz joint positions (style_metrics), mean over strokes.',
        '',
        *markdown.table(
            ['Actor', 'Direction', 'Peak joint speed (rad/s)', 'Peak joint acc. (rad/s²)', 'Mean |jerk| (rad/s³)'], rows
        ),
        '',
        f'![smoothness]({SMOOTHNESS_PNG})',
        '',
    ]


def strips_section(strips: Sequence[dict]) -> list[str]:
    """The strips of frames and joint-angle charts, one per demonstrated direction."""
    lines = ['## Strokes beside the demonstrations', '']
    if not strips:
        return [*lines, 'No ball came from a demonstrated direction: no strip.', '']
    for entry in strips:
        lines.append(
            f'{entry["direction"].capitalize()}: seed {entry["seed"]}, ball {entry["ball"]} '
            f'({entry["launch_speed_m_s"]} m/s); PPO {entry["outcomes"]["ppo"]}, new style actor '
            f'{entry["outcomes"]["style"]}; the original (x1) demonstration nearest to its stroke: clip '
            f'{entry["demonstration_clip"]} '
            f'(`{entry["demonstration_source"]}`), DTW {entry["dtw_to_it_rad"]} rad.'
        )
        lines.append('')
        lines.append(
            f'![{entry["direction"]} strip]({entry["strip"]})'
            if entry['strip']
            else f'Strip of frames {entry["strip_missing"]}.'
        )
        lines += ['', f'![{entry["direction"]} joints]({entry["joints"]})', '']
    return lines


def run_section(timings_s: Mapping[str, float], checkpoints) -> list[str]:
    """Wall time of each stage and the chosen checkpoints, as given."""
    rows = [[stage, f'{seconds:.0f}', f'{seconds / 60:.1f}'] for stage, seconds in timings_s.items()]
    total = sum(timings_s.values())
    rows.append(['**total**', f'{total:.0f}', f'{total / 60:.1f}'])
    return [
        '## The run',
        '',
        *markdown.table(['Stage', 'Wall time (s)', '(min)'], rows),
        '',
        'Chosen checkpoints:',
        '',
        '```',
        json.dumps(checkpoints, indent=2, default=str),
        '```',
        '',
    ]


# ---------------------------------------------------------------------------------------------------


def write_report(run_dir: str | os.PathLike, *, dataset_path: str | os.PathLike, **options) -> pathlib.Path:
    """Write RUN/report.md, report.json and the PNGs from RUN/EVAL_DIR's files (module docstring).

    write_report_of with the evaluations read from RUN and the dataset from dataset_path; `options` are
    write_report_of's keywords after `source` (timings_s and checkpoints required, notes, render_strips,
    strip_directions). Returns the report's path; ValueError naming a missing or DTW-less evaluation file."""
    from stylepong_policy.training.dataset import ReferenceDataset

    run_dir = pathlib.Path(run_dir)
    results = {name: load_actor_results(run_dir, name, high_required=name == 'style') for name in ACTORS}
    dataset_name = pathlib.Path(dataset_path).name
    source = f'stylepong_policy.reports.style_report from `{EVAL_DIR}/`'
    dataset = ReferenceDataset.load(dataset_path)
    return write_report_of(run_dir, results, dataset, dataset_name=dataset_name, source=source, **options)


def write_report_of(
    out_dir: str | os.PathLike,
    results: Mapping[str, ActorResults],
    dataset,
    *,
    dataset_name: str,
    source: str,
    timings_s: Mapping[str, float],
    checkpoints,
    notes: Sequence[str] = (),
    render_strips: bool = True,
    strip_directions: Sequence[str] | None = None,
) -> pathlib.Path:
    """write_report from evaluations already in hand: `results` for each of ACTORS (an ActorResults whose
    all-speeds summary has DTW against `dataset`; high_speeds may be None for every actor), written to
    OUT/report.md, report.json and the PNGs. dataset_name: how the report names the demonstrations;
    source: what wrote the report (after 'by' in its first line); timings_s: wall time of each stage, in
    order; checkpoints: what was chosen (any JSON-able value); notes: lines printed under the title (e.g.
    how labels without clips were handled); strip_directions: the directions that get a strip and joint
    chart (None: every demonstrated one; each takes a few seconds to draw); render_strips=False draws the
    joint charts alone. Returns the report's path. style_confusion calls this with the evaluations it ran,
    so that a report costs no evaluation of its own."""
    out_dir = pathlib.Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    rate_hz = results['style'].rate_hz
    distances = {name: dtw_by_direction(r.all_speeds) for name, r in results.items()}
    ratios = dtw_ratios(distances)
    column_phases = {name: phases_by_column(r.all_speeds) for name, r in results.items()}
    phases = {name: by_column[OVERALL] for name, by_column in column_phases.items()}
    originals = dataset.label[dataset.speed_factor == 1].tolist()
    clips = {d: originals.count(d) for d in DIRECTIONS}
    reference = style_metrics.reference_smoothness(dataset, DIRECTIONS, speed_factor=1)  # the originals
    setting = setting_text(results['style'].all_speeds)

    from stylepong_policy.reports import paper_charts

    success_chart(out_dir / SUCCESS_PNG, results)
    dtw_chart(out_dir / DTW_PNG, distances, ratios, setting)
    paper_charts.smoothness_chart(
        out_dir / SMOOTHNESS_PNG,
        {ACTOR_TITLES[n]: r.all_speeds['smoothness'] for n, r in results.items()},
        reference,
        setting,
    )
    shown = DIRECTIONS if strip_directions is None else tuple(strip_directions)
    strips = [
        entry
        for d in DIRECTIONS
        if clips[d] and d in shown
        for entry in [strip_for_direction(out_dir, results, dataset, d, rate_hz, render_strips)]
        if entry
    ]

    lines = [
        '# A learned style: report',
        '',
        f'Generated {datetime.date.today().isoformat()} by {source}.',
        'The new style actor beside PPO (no style term) and the shipped style actor, on the same balls'
        + ('.' if _same_balls(results) else ' (NOT the same balls: the evaluations used different seeds).'),
        '',
    ]
    lines += [f'- {note}' for note in notes] + ([''] if notes else [])
    blades = {DEMONSTRATIONS: contacts.mean_blades(contacts.demonstrated_contacts(dataset))}
    blades |= {name: contacts.mean_blades(contacts.actor_contacts(r.strokes)) for name, r in results.items()}
    targets = targets_record(distances, column_phases, results['style'].all_speeds['success_rate'], blades)
    lines += targets_section(targets)
    lines += success_section(results)
    lines += dtw_section(results, distances, ratios, phases, dataset_name, clips)
    lines += contact_section(blades)
    lines += smoothness_section(results, reference)
    lines += strips_section(strips)
    if timings_s or checkpoints is not None:  # a report without a record of its run leaves the section out
        lines += run_section(timings_s, checkpoints)
    report = out_dir / REPORT_MD
    report.write_text('\n'.join(lines))
    record = {
        'setting': setting,
        'dataset': dataset_name,
        'clips_per_label': clips,
        'success': {
            n: {
                'all': r.all_speeds['success_rate'],
                'high': None if r.high_speeds is None else r.high_speeds['success_rate'],
            }
            for n, r in results.items()
        },
        'dtw_rad': distances,
        'dtw_ratios': ratios,
        'dtw_by_phase_rad': phases,
        'targets': targets,
        'blade_at_contact': blades,
        'smoothness': {n: r.all_speeds['smoothness'] for n, r in results.items()},
        'demonstration_smoothness': reference,
        'strips': strips,
        'timings_s': dict(timings_s),
        'checkpoints': checkpoints,
        'notes': list(notes),
    }
    (out_dir / REPORT_JSON).write_text(json.dumps(record, indent=2, default=str) + '\n')
    return report
