"""`ros2 run stylepong_policy style_generalisation`: learn_style on the drawn styles nobody tuned it for.

    style_generalisation --split DIR/split.json --runs RUNS_DIR --confusion OUT/style_confusion.json --out results/

Reads the split that tools/drawn_styles.py generate wrote (its `heldout` styles; the `tuning` half is never
shown), each held-out style's learn_style run RUNS_DIR/<style>/ (learn_style.json: the stages and their wall
times, the device; report.json: the `targets` of style_report.targets_record and the evaluation setting) and
style_confusion's JSON over the shipped set and the held-out sets. Writes OUT/style_generalisation.md and
.json: a row per held-out set (wall time, success, the ratios to PPO's and to the shipped style actor's DTW
overall and per direction, each met or missed, and whether the run met every target; a missing or unfinished
run is listed as such), how many sets met every target, the confusion matrix copied from that JSON, the
setting and the command line.

The held-out sets are meant to be reported once. So the JSON keeps `looks`, how many times the held-out
figures were written: the previous OUT/style_generalisation.json is read, and the count goes up by one when
the held-out set names or their runs' report.json (by SHA-256) changed since; the first writing is look 1.
The markdown prints the count beside the table.

No rclpy, no torch: it reads JSON files. Exit status 0, 2 for a missing or malformed input (one line).
"""

from __future__ import annotations

import argparse
import datetime
import hashlib
import json
import pathlib
import sys
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any, NoReturn

from stylepong_common import markdown
from stylepong_common.command_line import exit_with_run, ros2_run_line
from stylepong_policy.evaluation.strokes import DIRECTIONS
from stylepong_policy.reports.style_report import (
    OVERALL,
    REPORT_JSON,
    TARGET_RATIOS,
    TARGET_SUCCESS_RATE,
    VERDICT_WORDS,
)
from stylepong_policy.training.learn_style import STAGES, STATE_NAME

PROG = 'style_generalisation'
MARKDOWN_NAME = 'style_generalisation.md'
JSON_NAME = 'style_generalisation.json'
HELDOUT, TUNING = 'heldout', 'tuning'  # split.json's keys (style_space.split_tuning_heldout)
# The table's order: overall first, the headline figure; then each direction (style_report.COLUMNS' set).
TABLE_COLUMNS = (OVERALL, *DIRECTIONS)
FINISHED, UNFINISHED, MISSING, NO_TARGETS = 'finished', 'unfinished', 'missing', 'no targets'


class InputError(Exception):
    """An input that is missing or not what its writer writes: one line for stderr."""


# ---------------------------------------------------------------------------------------------------
# Inputs


def read_json(path: pathlib.Path, what: str) -> Any:
    """A JSON document; InputError naming the file and `what` wrote it when it is missing or not JSON."""
    if not path.is_file():
        raise InputError(f'{path}: missing ({what} writes it)')
    try:
        return json.loads(path.read_text())
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as error:
        raise InputError(f'{path}: malformed, not the JSON {what} writes ({error})') from error


def _names(value: Any) -> bool:
    return isinstance(value, list) and all(isinstance(name, str) and name for name in value)


def heldout_sets(split_path: pathlib.Path) -> list[str]:
    """The held-out style names of a drawn_styles split, in its order; InputError when the split is malformed
    (no list of names under `heldout` or `tuning`, or a style in both halves: no held-out set then)."""
    split = read_json(split_path, 'tools/drawn_styles.py generate')
    if not isinstance(split, dict) or not _names(split.get(HELDOUT)) or not _names(split.get(TUNING)):
        raise InputError(f'{split_path}: malformed, no lists of style names under {HELDOUT!r} and {TUNING!r}')
    both = sorted(set(split[HELDOUT]) & set(split[TUNING]))
    if both:
        raise InputError(f'{split_path}: malformed, {both[0]} is in both the tuning and the held-out half')
    return list(split[HELDOUT])


@dataclass(frozen=True)
class HeldoutRun:
    """What one held-out style's learn_style run says, as far as it got."""

    name: str
    path: str
    status: str  # FINISHED, UNFINISHED, MISSING or NO_TARGETS (a report written before it had targets)
    stages_done: int
    wall_time_min: float | None  # the stages' wall times added up (so far, when unfinished)
    budget_min: float | None  # learn_style's --minutes
    device: str | None  # learn_style.json records the torch device, not the machine
    setting: str | None  # the evaluation setting of its report (seeds, balls)
    targets: dict | None  # report.json's `targets` (style_report.targets_record)
    report_sha256: str | None


def file_sha256(path: pathlib.Path) -> str | None:
    """The SHA-256 of a file's bytes; None when there is no file."""
    return hashlib.sha256(path.read_bytes()).hexdigest() if path.is_file() else None


def read_run(runs_dir: pathlib.Path, name: str) -> HeldoutRun:
    """RUNS_DIR/<name>/ read; a run with no learn_style.json is MISSING, one whose report stage is not done
    UNFINISHED. InputError when its learn_style.json or report.json is not JSON."""
    run_dir = runs_dir / name
    state_path, report_path = run_dir / STATE_NAME, run_dir / REPORT_JSON
    if not state_path.is_file():
        return HeldoutRun(name, run_dir.as_posix(), MISSING, 0, None, None, None, None, None, None)
    state = read_json(state_path, 'learn_style')
    stages = state.get('stages', {}) if isinstance(state, dict) else None
    if not isinstance(stages, dict):
        raise InputError(f'{state_path}: malformed, no stages in it')
    seconds = sum(facts.get('wall_time_s', 0.0) for facts in stages.values() if isinstance(facts, dict))
    finished = 'report' in stages and report_path.is_file()
    report = read_json(report_path, 'learn_style (style_report)') if finished else {}
    targets = report.get('targets') if isinstance(report, dict) else None
    status = UNFINISHED if not finished else FINISHED if isinstance(targets, dict) else NO_TARGETS
    return HeldoutRun(
        name=name,
        path=run_dir.as_posix(),
        status=status,
        stages_done=len([s for s in STAGES if s in stages]),
        wall_time_min=round(seconds / 60.0, 1),
        budget_min=state.get('minutes'),
        device=state.get('device'),
        setting=report.get('setting') if isinstance(report, dict) else None,
        targets=targets if status == FINISHED else None,
        report_sha256=file_sha256(report_path),
    )


def confusion_matrix(path: pathlib.Path) -> dict:
    """What the table copies from style_confusion's JSON: its command, date, setting, baseline, the sets and
    actors, each actor's normalised overall distance to each set and its verdict (nearest set, margin).
    InputError when the file is missing or lacks any of these."""
    record = read_json(path, 'style_confusion')
    try:
        sets, actors = list(record['sets']), list(record['actors'])
        matrix = {a: {s: record['normalised'][a][s][OVERALL] for s in sets} for a in actors}
        verdicts = {
            a: {key: record['verdicts'][a][key] for key in ('nearest', 'margin', 'margin_ratio', 'nearest_is_own')}
            for a in actors
        }
        copied = {key: record[key] for key in ('command', 'generated', 'setting', 'baseline')}
    except (KeyError, TypeError) as error:
        why = f'no key {error}' if isinstance(error, KeyError) else str(error)
        raise InputError(f'{path}: malformed, not the JSON style_confusion writes ({why})') from error
    return {
        'file': path.as_posix(),
        **copied,
        'sets': sets,
        'actors': actors,
        'normalised': matrix,
        'verdicts': verdicts,
    }


# ---------------------------------------------------------------------------------------------------
# Figures


def met_every_target(run: HeldoutRun) -> bool:
    """Every target of its report met (a target not measured is no pass; a run without targets met none)."""
    count = run.targets['count'] if run.targets else None
    return bool(count) and count['met'] == count['targets']


def row_record(run: HeldoutRun) -> dict:
    """One held-out set's figures: the run's state, success and each ratio against its target."""
    keys = ('path', 'status', 'stages_done', 'wall_time_min', 'budget_min', 'device', 'setting')
    record = {key: getattr(run, key) for key in keys}
    record['stages'] = len(STAGES)
    if run.targets is not None:
        record['success'] = run.targets['success']
        record['ratios'] = {
            column: {
                name: {key: run.targets['dtw'][column][name][key] for key in ('ratio', 'target', 'met')}
                for name in TARGET_RATIOS
            }
            for column in TABLE_COLUMNS
        }
        record['count'] = run.targets['count']
    record['met_every_target'] = met_every_target(run)
    return record


def next_look(previous_path: pathlib.Path, reports: Mapping[str, str | None]) -> int:
    """This writing's look: 1 without a previous record; the previous count when the held-out sets and their
    reports are the ones it was written from (a rerun shows nothing new), else one more. InputError when the
    previous record is malformed: starting the count again would hide the looks it holds."""
    if not previous_path.is_file():
        return 1
    previous = read_json(previous_path, PROG)
    if not isinstance(previous, dict) or not isinstance(previous.get('looks'), int):
        raise InputError(f'{previous_path}: malformed, no count of looks in it to carry on')
    changed = previous.get('reports_sha256') != dict(reports)
    return previous['looks'] + int(changed)


# ---------------------------------------------------------------------------------------------------
# Markdown


def _ratio_cell(check: Mapping) -> str:
    value = 'n/a' if check['ratio'] is None else f'{check["ratio"]:.3f}'
    return f'{value}, {VERDICT_WORDS[check["met"]]}'


def _run_cell(row: Mapping) -> str:
    if row['status'] == UNFINISHED:
        return f'unfinished ({row["stages_done"]} of {row["stages"]} stages)'
    if row['status'] == NO_TARGETS:
        return 'finished; its report.json has no targets (written before they were reported)'
    return row['status']


def table_rows(rows: Mapping[str, Mapping]) -> list[list[str]]:
    """The held-out table's cells: a run without targets has none of the figures, and met no target."""
    lines = []
    for name, row in rows.items():
        minutes = '-' if row['wall_time_min'] is None else f'{row["wall_time_min"]:.1f}'
        if row['status'] == UNFINISHED:
            minutes += ' so far'
        figures = ['-'] * (1 + len(TABLE_COLUMNS) * len(TARGET_RATIOS))
        if 'ratios' in row:
            success = row['success']
            figures = [f'{100 * success["rate"]:.1f} %, {VERDICT_WORDS[success["met"]]}']
            figures += [_ratio_cell(row['ratios'][c][n]) for c in TABLE_COLUMNS for n in TARGET_RATIOS]
        lines.append([f'`{name}`', _run_cell(row), minutes, *figures, 'yes' if row['met_every_target'] else 'no'])
    return lines


def table_header() -> list[str]:
    """The held-out table's header: each target beside its figure."""
    targets = TARGET_RATIOS.items()
    ratios = [f'{column} {name} (<= {target:.2f})' for column in TABLE_COLUMNS for name, target in targets]
    success = f'Success (>= {100 * TARGET_SUCCESS_RATE:.0f} %)'
    return ['Held-out set', 'Run', 'Wall time (min)', success, *ratios, 'Met every target']


def looks_text(looks: int) -> str:
    """The line beside the table: how many times the held-out figures were looked at."""
    return (
        f'Held-out sets looked at {looks} time{"" if looks == 1 else "s"}: the count goes up each time this '
        "file is written from held-out figures that changed (set names, or a run's report.json), since the "
        'project reports held-out sets once and says how often they were looked at.'
    )


def _distance(value: float | None) -> str:
    return 'n/a' if value is None else f'{value:.3f}'


def confusion_section(confusion: Mapping, heldout: Sequence[str]) -> list[str]:
    """The confusion matrix as style_confusion wrote it (normalised overall distances, each actor's nearest
    set in bold), with the file it came from and how many held-out actors are nearest their own set."""
    sets, verdicts = confusion['sets'], confusion['verdicts']
    rows = []
    for actor in confusion['actors']:
        nearest = verdicts[actor]['nearest']
        cells = [
            f'**{_distance(value)}**' if s == nearest else _distance(value)
            for s, value in confusion['normalised'][actor].items()
        ]
        margin = verdicts[actor]['margin_ratio']
        ratio = 'n/a' if margin is None else f'{margin:.2f}'
        rows.append([f'`{actor}`', *cells, f'`{nearest}`' if nearest else 'n/a', ratio])
    own = [a for a in heldout if a in verdicts and verdicts[a]['nearest_is_own'] is not None]
    nearest_own = sum(bool(verdicts[a]['nearest_is_own']) for a in own)
    lines = [
        '## Style confusion over all sets',
        '',
        f'Copied from `{confusion["file"]}` (written {confusion["generated"]} by `{confusion["command"]}`). '
        "Each actor's mean DTW distance to each set's clips over the baseline's (`"
        f'{confusion["baseline"]}`, PPO: no style) on the same set; smaller is nearer, bold the nearest set. '
        f'Setting: {confusion["setting"]}.',
        '',
        *markdown.table(['Actor', *(f'`{s}`' for s in sets), 'nearest', 'next / nearest'], rows),
        '',
        f'Held-out actors nearest their own set: {nearest_own} of {len(own)} in the matrix.',
    ]
    absent = [name for name in heldout if name not in sets]
    if absent:
        lines.append(f'Held-out sets not in the matrix: {", ".join(f"`{n}`" for n in absent)}.')
    return [*lines, '']


def _by_value(values: Mapping[str, str | None]) -> str:
    """'A (s1, s2); B (s3)': each distinct value and the sets it holds for."""
    grouped: dict[str, list[str]] = {}
    for name, value in values.items():
        if value is not None:
            grouped.setdefault(value, []).append(name)
    return '; '.join(f'{value} ({", ".join(names)})' for value, names in grouped.items()) or 'none yet'


def setting_section(record: Mapping) -> list[str]:
    """Where the figures come from: the evaluation setting of each report, the budget and device of each
    run, the command that wrote this file."""
    rows = record['heldout']
    settings = _by_value({name: row['setting'] for name, row in rows.items()})
    budgets = {
        name: row['budget_min'] and f'{row["budget_min"]:g} min on {row["device"]}' for name, row in rows.items()
    }
    return [
        '## Setting',
        '',
        f'- Split: `{record["split"]}` (held-out half only; the tuning half is never shown here). Runs: '
        f'`{record["runs"]}/<set>/`.',
        f'- Evaluation of each finished run (its report.json): {settings}.',
        f"- learn_style's budget and device (learn_style.json, which records no more of the machine): "
        f'{_by_value(budgets)}.',
        f'- Written {record["generated"]} by `{record["command"]}`.',
        '',
    ]


def render_markdown(record: Mapping) -> str:
    """style_generalisation.md from the JSON record."""
    summary = record['summary']
    lines = [
        '# learn_style on held-out drawn styles',
        '',
        'Styles drawn from the space of strokes and held out of every tuning (tools/drawn_styles.py), each '
        "learned by learn_style; each run's ratios of its new actor's mean DTW to its "
        "demonstrations over PPO's and over the shipped style actor's, and its success at all speeds, against "
        "learn_style's targets (style_report).",
        '',
        f'**{summary["met_every_target"]} of {summary["sets"]} held-out sets met every target** '
        f'({summary["finished"]} of {summary["sets"]} runs finished).',
        '',
        looks_text(record['looks']),
        '',
        *markdown.table(table_header(), table_rows(record['heldout'])),
        '',
    ]
    lines += confusion_section(record['confusion'], list(record['heldout']))
    lines += setting_section(record)
    return '\n'.join(lines)


# ---------------------------------------------------------------------------------------------------
# Command line


def build_parser() -> argparse.ArgumentParser:
    """The command line of style_generalisation."""
    parser = argparse.ArgumentParser(prog=PROG, description=__doc__.split('\n\n')[0])
    parser.add_argument('--split', required=True, type=pathlib.Path, help="drawn_styles.py generate's split.json")
    parser.add_argument('--runs', required=True, type=pathlib.Path, help="the held-out styles' runs, RUNS/<style>/")
    parser.add_argument(
        '--confusion', required=True, type=pathlib.Path, help='style_confusion.json over the held-out sets'
    )
    parser.add_argument('--out', required=True, type=pathlib.Path, help='folder for the .md and .json')
    return parser


def build_record(args: argparse.Namespace, argv: Sequence[str]) -> dict:
    """The JSON record from the inputs (InputError: one line on what is wrong)."""
    names = heldout_sets(args.split)
    confusion = confusion_matrix(args.confusion)
    runs = [read_run(args.runs, name) for name in names]
    reports = {run.name: run.report_sha256 for run in runs}
    rows = {run.name: row_record(run) for run in runs}
    return {
        'command': ros2_run_line('stylepong_policy', PROG, argv),
        'generated': datetime.date.today().isoformat(),
        'split': args.split.as_posix(),
        'runs': args.runs.as_posix(),
        'looks': next_look(args.out / JSON_NAME, reports),
        'reports_sha256': reports,
        'summary': {
            'sets': len(runs),
            'finished': sum(run.status != MISSING and run.status != UNFINISHED for run in runs),
            'met_every_target': sum(row['met_every_target'] for row in rows.values()),
        },
        'targets': {'ratios': TARGET_RATIOS, 'success_rate': TARGET_SUCCESS_RATE},
        'heldout': rows,
        'confusion': confusion,
    }


def run(argv: Sequence[str] | None = None) -> int:
    """Read, count the look, write (module docstring); returns the exit code."""
    argv = list(sys.argv[1:] if argv is None else argv)
    args = build_parser().parse_args(argv)
    try:
        record = build_record(args, argv)
    except InputError as error:
        print(f'{PROG}: {error}', file=sys.stderr)
        return 2
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / JSON_NAME).write_text(json.dumps(record, indent=2) + '\n')
    (args.out / MARKDOWN_NAME).write_text(render_markdown(record))
    summary = record['summary']
    print(
        f'{PROG}: {summary["met_every_target"]} of {summary["sets"]} held-out sets met every target; '
        f'look {record["looks"]}; wrote {args.out / MARKDOWN_NAME} and {JSON_NAME}'
    )
    return 0


def main(argv: Sequence[str] | None = None) -> NoReturn:
    """Entry point of the style_generalisation executable (exit code 130 on Ctrl-C)."""
    exit_with_run(PROG, run, argv)


if __name__ == '__main__':
    main()
