"""`ros2 run stylepong_policy build_dataset BAG_OR_DIR... -o DATASET.npz`: the training bridge.

Turns rosbag2 recordings of an arm (the teaching clips in ros2_ws/bags, or any bag from a real UR
driver) into the reference motions the AMP discriminator learns from: 60 Hz clips of joint positions
and velocities in URDF order, plus the paper's x2/x3/x5 sped-up copies. Prints one report entry per bag
(used, or skipped and why); a bad bag never stops the others.

Exit status: 0 when at least one clip was written, 1 when none was (or, with --strict, when anything
went wrong), 2 for invalid arguments.
"""

from __future__ import annotations

import argparse
import pathlib
import re
import sys
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import NoReturn

from stylepong_common.command_line import exit_with_run
from stylepong_policy.evaluation.strokes import DIRECTIONS
from stylepong_policy.training.dataset import (
    DEFAULT_RATE_HZ,
    DEFAULT_SPEEDUPS,
    Clip,
    ClipOptions,
    SourceClip,
    assemble_dataset,
    make_clips,
    parse_speedups,
)
from stylepong_recording.bag_errors import BagError, one_line
from stylepong_recording.bag_reading import median_rate_hz, read_joint_states
from stylepong_recording.bag_search import find_bags
from stylepong_recording.clip_writer import label_from_bag_dir_name

UNLABELLED = 'unlabelled'
# Bags from elsewhere named <label>_<time> (forward_2025-11-21...): letters, '_', then a digit. rosbag2's
# default rosbag2_<date> carries no label and does not match (the digit in 'rosbag2').
_DIRECTORY_LABEL = re.compile(r'^([A-Za-z][A-Za-z-]*)_\d')
# Names split into words at anything that is not a letter: 'take3_forward', 'forward-02' and 'Forward1'
# each hold the word 'forward'.
_NAME_WORDS = re.compile(r'[^a-z]+')


def default_joint_names() -> tuple[str, ...]:
    """The UR5's joint names in URDF order."""
    from stylepong_description.robot_model import JOINT_NAMES

    return tuple(JOINT_NAMES)


def label_from_name(name: str) -> str | None:
    """The label a bag directory's name carries, or None: the recorder's own names
    (<label>_<YYYYmmdd>_<HHMMSS>_<ms>, any label it accepts), then a name with one stroke direction among
    its words (direction_in_name)."""
    return label_from_bag_dir_name(name) or direction_in_name(name)


def direction_in_name(name: str) -> str | None:
    """The stroke direction (strokes.DIRECTIONS) that is a word of the name, in any case, or None when
    none is or several are: how other tools name a take ('forward_03', 'take3-leftward', 'Rightward2')."""
    found = {word for word in _NAME_WORDS.split(name.lower()) if word in DIRECTIONS}
    return found.pop() if len(found) == 1 else None


@dataclass
class BagReport:
    """What became of one bag: its clips and label, or why it was skipped."""

    path: pathlib.Path
    reason: str | None = None  # why the bag gave no clip; None when used
    topic: str = ''
    label: str = ''
    label_origin: str = ''
    summary: str = ''
    clips: list[Clip] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)
    problems: list[str] = field(default_factory=list)

    @property
    def used(self) -> bool:
        return self.reason is None


def choose_label(bag: pathlib.Path, from_metadata: str | None, fallback: str | None) -> tuple[str, str]:
    """A bag's label and where it came from: metadata, the directory name, the folder holding it (one
    folder per direction: forward/take_1/), a name like <letters>_<digit>..., --label, or none."""
    if from_metadata:
        return from_metadata, 'metadata custom_data'
    name = bag.name if bag.is_dir() else bag.stem
    name_label = label_from_name(name)
    if name_label:
        return name_label, 'directory name'
    folder_label = direction_in_name(bag.parent.name)
    if folder_label:
        return folder_label, 'folder name'
    match = _DIRECTORY_LABEL.match(name)
    if match:
        return match.group(1), 'directory name'
    if fallback:
        return fallback, '--label'
    return UNLABELLED, 'none in custom_data, the directory name or its folder; --label sets one'


@dataclass(frozen=True)
class BuildSettings:
    """What becomes of the bags: the command line's options, for callers in Python."""

    topic: str | None = None  # None: the bag's one JointState topic
    joints: tuple[str, ...] = ()  # (): the URDF's joints
    assume_order: bool = False  # names missing: take the positions in `joints` order
    speedups: tuple[int, ...] = DEFAULT_SPEEDUPS
    label: str | None = None  # for bags that carry none
    strict: bool = False  # any problem: write nothing, exit status 1
    clip_options: ClipOptions = field(default_factory=ClipOptions)
    plot: pathlib.Path | None = None  # also a figure of the clips

    def arm_joints(self) -> tuple[str, ...]:
        return tuple(self.joints) or default_joint_names()


def process_bag(bag: pathlib.Path, settings: BuildSettings) -> BagReport:
    """Read one bag and cut its clips; every failure becomes the report's reason, never an exception."""
    report = BagReport(path=bag)
    options = settings.clip_options
    try:
        recording = read_joint_states(
            bag, topic=settings.topic, joints=settings.arm_joints(), assume_order=settings.assume_order
        )
    except BagError as error:
        report.reason = str(error)
        return report
    except Exception as error:  # noqa: BLE001  a bag must never stop the tool
        report.reason = f'unreadable: {one_line(error)}'
        return report
    report.topic = recording.topic
    report.problems.extend(recording.problems)
    report.notes.extend(recording.notes)
    report.label, report.label_origin = choose_label(bag, recording.label, settings.label)
    rate = median_rate_hz(
        recording.header_stamp_ns if (recording.header_stamp_ns > 0).all() else recording.receive_time_ns
    )
    report.summary = f'{recording.topic}: {recording.message_count} msgs, {rate:.0f} Hz' + (
        f', {recording.storage}' if recording.storage else ''
    )
    try:
        result = make_clips(
            recording.header_stamp_ns,
            recording.receive_time_ns,
            recording.position_rad,
            recording.velocity_rad_s,
            options,
        )
    except Exception as error:  # noqa: BLE001
        report.reason = f'{recording.topic}: could not make clips: {one_line(error)}'
        return report
    report.notes.extend(result.notes)
    report.clips = result.clips
    if not result.clips:
        report.reason = f'{recording.topic}: no clip: {"; ".join(result.notes) if result.notes else "no motion"}'
    return report


def format_report(report: BagReport, speedups: Sequence[int], rate_hz: float) -> list[str]:
    """The lines build_dataset prints for one bag."""
    lines = []
    if report.used:
        clip_text = '; '.join(
            f'{len(c) / rate_hz:.2f} s, {len(c)} frames'
            + (' (' + ', '.join(f'x{k} {-(-len(c) // k)}' for k in speedups) + ')' if speedups else '')
            + f', velocity from {"the bag" if c.velocity_source == "bag" else "positions"}'
            + ('' if c.time_source == 'header' else ', timed by receive time')
            for c in report.clips
        )
        lines.append(f'[used]    {report.path}  {report.summary}; label {report.label!r} ({report.label_origin})')
        lines.append(f'          {len(report.clips)} clip(s): {clip_text}')
    else:
        lines.append(f'[skipped] {report.path}: {report.reason}')
    lines += [f'          note: {n}' for n in report.notes if report.used]
    lines += [f'          problem: {p}' for p in report.problems]
    return lines


def _comma_list(text: str) -> tuple[str, ...]:
    items = tuple(part.strip() for part in text.split(',') if part.strip())
    if not items:
        raise argparse.ArgumentTypeError('needs at least one name')
    if len(set(items)) != len(items):
        raise argparse.ArgumentTypeError(f'repeated name in {text!r}')
    return items


def _speedups(text: str) -> tuple[int, ...]:
    try:
        return parse_speedups(text)
    except ValueError as error:
        raise argparse.ArgumentTypeError(str(error)) from None


def build_parser() -> argparse.ArgumentParser:
    """The command-line parser of build_dataset."""
    defaults = ClipOptions()
    parser = argparse.ArgumentParser(
        prog='build_dataset', description=__doc__.split('\n\n')[1], epilog=__doc__.split('\n\n')[2]
    )
    parser.add_argument(
        'bags',
        nargs='+',
        metavar='BAG_OR_DIR',
        help='bag directories (or .mcap/.db3 files), or directories searched for bags',
    )
    parser.add_argument('-o', '--output', required=True, type=pathlib.Path, help='dataset file to write (.npz)')
    parser.add_argument('--topic', default=None, help="JointState topic (default: the bag's only JointState topic)")
    parser.add_argument(
        '--joints',
        type=_comma_list,
        default=None,
        help='comma-separated joint names in output order (default: the UR5 joints in URDF order)',
    )
    parser.add_argument(
        '--assume-order', action='store_true', help='messages with an empty name[] list positions in --joints order'
    )
    parser.add_argument('--rate-hz', type=float, default=DEFAULT_RATE_HZ, help='clip frame rate (default %(default)s)')
    parser.add_argument(
        '--speedups',
        type=_speedups,
        default=DEFAULT_SPEEDUPS,
        help="comma-separated speed-up factors for augmentation, default 2,3,5 ('none': originals only)",
    )
    parser.add_argument(
        '--idle-speed-rad-s',
        type=float,
        default=defaults.idle_speed_rad_s,
        help='lead-in/lead-out frames whose fastest joint is slower are trimmed (default %(default)s; 0: no trim)',
    )
    parser.add_argument(
        '--max-gap-s',
        type=float,
        default=defaults.max_gap_s,
        help='a longer silence in a recording (or 5 message periods) splits it into clips (default %(default)s)',
    )
    parser.add_argument(
        '--label', default=None, help='label for bags with none in metadata custom_data or the directory name'
    )
    parser.add_argument(
        '--plot',
        type=pathlib.Path,
        default=None,
        metavar='PNG',
        help="write a figure of every clip's joint trajectories",
    )
    parser.add_argument(
        '--strict', action='store_true', help='any problem (a skipped bag, lost messages) is fatal: nothing is written'
    )
    return parser


def _ros_free_argv(argv: Sequence[str]) -> list[str]:
    """Drop a trailing --ros-args section (added by launch files); this tool takes no ROS arguments."""
    argv = list(argv)
    return argv[: argv.index('--ros-args')] if '--ros-args' in argv else argv


def settings_from_args(args: argparse.Namespace) -> BuildSettings:
    """The command line's options as BuildSettings."""
    options = ClipOptions(rate_hz=args.rate_hz, idle_speed_rad_s=args.idle_speed_rad_s, max_gap_s=args.max_gap_s)
    return BuildSettings(
        topic=args.topic,
        joints=tuple(args.joints or ()),
        assume_order=args.assume_order,
        speedups=tuple(args.speedups),
        label=args.label,
        strict=args.strict,
        clip_options=options,
        plot=args.plot,
    )


def run(argv: Sequence[str] | None = None) -> int:
    """Build a dataset from the bags on the command line; returns the exit code."""
    parser = build_parser()
    args = parser.parse_args(_ros_free_argv(sys.argv[1:] if argv is None else argv))
    try:
        return build(args.bags, args.output, settings_from_args(args))
    except ValueError as error:
        parser.error(str(error))


def build(bags: Sequence[str | pathlib.Path], output: pathlib.Path, settings: BuildSettings = BuildSettings()) -> int:
    """Build a dataset from `bags` (bags or folders holding them) into `output`, printing one report entry
    per bag; returns the exit status (0: written; 1: no clip, or a problem under `strict`). ValueError for
    settings that make no sense."""
    options = settings.clip_options
    options.validate()
    output = pathlib.Path(output)
    if output.is_dir():
        raise ValueError(f'--output {output} is a directory; give a file name such as dataset.npz')
    search = find_bags(bags)
    problems = 0
    for path, reason in search.rejected:
        print(f'[skipped] {path}: {reason}', flush=True)
        problems += 1
    reports = []
    for bag in search.bags:
        report = process_bag(bag, settings)
        reports.append(report)
        print('\n'.join(format_report(report, settings.speedups, options.rate_hz)), flush=True)
        problems += len(report.problems) + (0 if report.used else 1)

    originals = [SourceClip(clip, r.label, f'{r.path}:{r.topic}') for r in reports if r.used for clip in r.clips]
    used = sum(r.used for r in reports)
    tally = (
        f'{used} of {len(search.bags)} bag(s) used, {len(search.bags) - used + len(search.rejected)} skipped, '
        f'{problems} problem(s)'
    )
    if settings.strict and problems:
        print(f'build_dataset: --strict and {problems} problem(s): nothing written ({tally})', file=sys.stderr)
        return 1
    if not originals:
        print(f'build_dataset: no clip, nothing written ({tally})', file=sys.stderr)
        return 1
    dataset = assemble_dataset(originals, settings.speedups, settings.arm_joints(), options.rate_hz)
    try:
        dataset.save(output)
    except OSError as error:
        print(f'build_dataset: cannot write {output}: {one_line(error)}', file=sys.stderr)
        return 1
    print(
        f'wrote {output}: {dataset.num_clips} clips ({len(originals)} original + '
        f'{dataset.num_clips - len(originals)} sped up '
        f'{"x" + "/x".join(map(str, settings.speedups)) if settings.speedups else ""}'
        f'), {len(dataset.t)} frames at {options.rate_hz:g} Hz; {tally}'
    )
    if settings.plot is not None:
        try:
            from stylepong_policy.reports.dataset_plot import plot_dataset

            plot_dataset(dataset, settings.plot)
            print(f'wrote {settings.plot}')
        except Exception as error:  # noqa: BLE001  the dataset is written; a failed figure is only reported
            print(f'build_dataset: could not write the figure {settings.plot}: {one_line(error)}', file=sys.stderr)
            return 0 if not settings.strict else 1
    return 0


def main(argv: Sequence[str] | None = None) -> NoReturn:
    """Entry point of the build_dataset executable (exit code 130 on Ctrl-C)."""
    exit_with_run('build_dataset', run, argv)


if __name__ == '__main__':
    main()
