"""Checking a person's demonstrations before anything is trained on them (no rclpy, no torch).

`check_demonstrations(path, window_frames=L)` takes a folder of rosbag2 bags (or one bag), or a dataset
.npz written by build_dataset, and either returns what it found (a `DemonstrationSet`: the clips of
each label, cut as build_dataset cuts them) or raises `DemonstrationError`, whose message holds one
line per bad bag, each naming the bag and what is wrong with it:

  * the path does not exist, or holds no bag;
  * a bag that cannot be read (a cut or damaged storage file, no JointState topic, ...);
  * a bag without a label (none in metadata.yaml's custom_data, none in its directory's name or in the
    name of the folder holding it: build_dataset.choose_label), or with a label other than KNOWN_LABELS
    (the strokes the evaluation tells apart);
  * joints that are not the UR5's (another robot's recording);
  * a clip whose positions leave the UR5's joint limits (stylepong_description's robot model);
  * joint states slower than MIN_RATE_HZ: too few samples to resample to the policy's 60 Hz;
  * a clip too short for the discriminator: played at its largest speed-up (x5) it must still fill
    one window of `window_frames` frames at 60 Hz, or the discriminator never sees it.
A label with no clip is not a problem (the set says which labels it has); a set needs one clip.

A dataset .npz is checked for the same facts where it holds them: labels, joint names, limits, clip
lengths (every clip, sped-up ones included, must fill a window) and its frame rate (60 Hz). The joint
states' own rate is not in a dataset; build_dataset resampled them already. Its problems are named by
the bag each clip came from (the dataset's `source`).

Only bag reading, numpy and the robot model are imported, so a refusal comes in about a second.
"""

from __future__ import annotations

import math
import os
import pathlib
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from stylepong_policy.evaluation.strokes import DIRECTIONS
from stylepong_policy.training.build_dataset import UNLABELLED, choose_label, default_joint_names
from stylepong_policy.training.dataset import (
    DEFAULT_RATE_HZ,
    DEFAULT_SPEEDUPS,
    Clip,
    ClipOptions,
    ReferenceDataset,
    SourceClip,
    assemble_dataset,
    make_clips,
)
from stylepong_recording.bag_errors import BagError, one_line
from stylepong_recording.bag_reading import median_rate_hz, read_joint_states
from stylepong_recording.bag_search import find_bags

KNOWN_LABELS = DIRECTIONS
DATASET_SUFFIX = '.npz'
# Linear resampling to 60 Hz needs a sample at least every 60th of a second; 5 % below that allows for
# a recorder's jitter around a nominal 60 Hz.
MIN_RATE_HZ = 0.95 * DEFAULT_RATE_HZ
# Positions this far outside a limit are still within it (float rounding of a joint parked on its stop).
LIMIT_TOLERANCE_RAD = 1e-6
# bag_reading's reason when no message names every UR5 joint, and its hint meant for build_dataset.
_MISSING_JOINTS_REASON = 'no message carries all of the joints'
_JOINTS_OPTION_HINT = '; choose them with --joints'


class DemonstrationError(ValueError):
    """Demonstrations that must not be trained on; one line per bad bag (or for the folder), in `lines`."""

    def __init__(self, lines: Sequence[str]):
        self.lines = [line.replace('\n', ' ') for line in lines]
        super().__init__('\n'.join(self.lines))


@dataclass
class CheckedBag:
    """One bag that passed: its label, joint-state rate and the clips cut from it."""

    bag: pathlib.Path
    label: str
    rate_hz: float
    clips: list[Clip]
    source: str  # '<bag>:<topic>', the dataset's `source` of its clips
    notes: list[str] = field(default_factory=list)  # what bag reading recovered from (lost messages)


@dataclass
class DemonstrationSet:
    """Demonstrations that passed the checks: bags (`bags`) or a built dataset (`dataset`)."""

    path: pathlib.Path
    window_frames: int
    speedups: tuple[int, ...]
    bags: list[CheckedBag] = field(default_factory=list)
    dataset: ReferenceDataset | None = None

    @property
    def kind(self) -> str:
        return 'dataset' if self.dataset is not None else 'bags'

    def clips_per_label(self) -> dict[str, int]:
        """Original (x1) clips of each known label, zero for a label without any."""
        if self.dataset is not None:
            labels = self.dataset.label[self.dataset.speed_factor == 1].tolist()
        else:
            labels = [b.label for b in self.bags for _ in b.clips]
        return {label: labels.count(label) for label in KNOWN_LABELS}

    @property
    def labels_present(self) -> tuple[str, ...]:
        return tuple(label for label, count in self.clips_per_label().items() if count)

    @property
    def labels_missing(self) -> tuple[str, ...]:
        return tuple(label for label, count in self.clips_per_label().items() if not count)

    def reference_dataset(self) -> ReferenceDataset:
        """The discriminator's dataset: the bags' clips with their x2/x3/x5 copies (build_dataset's layout),
        or the dataset that was given, as it is."""
        if self.dataset is not None:
            return self.dataset
        originals = [SourceClip(clip, b.label, b.source) for b in self.bags for clip in b.clips]
        return assemble_dataset(originals, self.speedups, default_joint_names(), DEFAULT_RATE_HZ)

    def describe(self) -> str:
        """One line for a person: what was found, per label."""
        counts = ', '.join(f'{label} {count}' for label, count in self.clips_per_label().items())
        where = f'{len(self.bags)} bag(s)' if self.dataset is None else f'dataset of {self.dataset.num_clips} clips'
        missing = f'; no clip labelled {", ".join(self.labels_missing)}' if self.labels_missing else ''
        return f'{self.path}: {where}, original clips per label: {counts}{missing}'


# ---------------------------------------------------------------------------------------------------
# Facts checked on clips, whether cut from a bag or read from a dataset


def limit_violation(q_rad: np.ndarray, rate_hz: float) -> str | None:
    """Why a clip's positions leave the UR5's joint limits (the first joint and frame that do), or None."""
    from stylepong_description.robot_model import JOINT_NAMES, joint_limits

    limits = joint_limits()
    below = q_rad < limits.lower_rad - LIMIT_TOLERANCE_RAD
    above = q_rad > limits.upper_rad + LIMIT_TOLERANCE_RAD
    outside = below | above
    if not outside.any():
        return None
    frame, joint = (int(i) for i in np.argwhere(outside)[0])
    return (
        f'{JOINT_NAMES[joint]} at {q_rad[frame, joint]:.3f} rad, {frame / rate_hz:.2f} s into a clip, is outside '
        f"the UR5's limits [{limits.lower_rad[joint]:.3f}, {limits.upper_rad[joint]:.3f}] rad"
    )


def frames_after_speedup(frames: int, factor: int) -> int:
    """Frames of a clip of `frames` frames played `factor` times faster (dataset.speed_up keeps every k-th)."""
    return -(-frames // factor)


def shortness(frames: int, speedups: Sequence[int], window_frames: int, rate_hz: float) -> str | None:
    """Why a clip of `frames` frames is too short for the discriminator's window at its largest speed-up."""
    fastest = max(speedups, default=1)
    remaining = frames_after_speedup(frames, fastest)
    if remaining >= window_frames:
        return None
    needed_s = ((window_frames - 1) * fastest + 1) / rate_hz
    return (
        f'a clip of {frames / rate_hz:.2f} s ({frames} frames at {rate_hz:g} Hz) is too short: sped up x{fastest} '
        f"it has {remaining} frames, fewer than the discriminator's window of {window_frames}; "
        f'record at least {needed_s:.2f} s of motion'
    )


# ---------------------------------------------------------------------------------------------------
# Bags


def _read_reason(error: BaseException) -> str:
    """What reading a bag failed on, said for a person running learn_style rather than build_dataset."""
    text = str(error).strip().splitlines()[0] if str(error).strip() else ''
    if _MISSING_JOINTS_REASON in text and '(' in text:
        # '<topic>: no message carries all of the joints <UR5 joints> (<n> messages with joints [...]); hint'
        topic = text.split(':', 1)[0]
        found = text.split('(', 1)[1].replace(_JOINTS_OPTION_HINT, '').rstrip(')')
        return f"joints are not the UR5's (another robot's recording?): {topic} has {found}"
    return f'cannot be read: {one_line(error)}'


def check_bag(
    bag: pathlib.Path, *, window_frames: int, speedups: Sequence[int], topic: str | None = None
) -> CheckedBag:
    """One bag's clips, or BagError whose message is the bag's one line (naming it)."""
    try:
        recording = read_joint_states(bag, topic=topic, joints=default_joint_names())
    except Exception as error:  # noqa: BLE001  every way a bag fails is a refusal naming it
        raise BagError(f'{bag}: {_read_reason(error)}') from None
    label, origin = choose_label(bag, recording.label, None)
    if label == UNLABELLED:
        raise BagError(
            f'{bag}: unlabelled (no label in metadata.yaml custom_data, its directory name or its '
            f"folder's name); label it {', '.join(KNOWN_LABELS)}"
        )
    if label not in KNOWN_LABELS:
        raise BagError(f'{bag}: unknown label {label!r} (from its {origin}); the labels are {", ".join(KNOWN_LABELS)}')
    stamps = recording.header_stamp_ns if (recording.header_stamp_ns > 0).all() else recording.receive_time_ns
    rate_hz = median_rate_hz(stamps)
    if not (math.isfinite(rate_hz) and rate_hz >= MIN_RATE_HZ):
        raise BagError(
            f'{bag}: {recording.topic} at {rate_hz:.1f} Hz, too slow to resample to '
            f'{DEFAULT_RATE_HZ:g} Hz (needs {MIN_RATE_HZ:.0f} Hz or more)'
        )
    options = ClipOptions()
    result = make_clips(
        recording.header_stamp_ns, recording.receive_time_ns, recording.position_rad, recording.velocity_rad_s, options
    )
    if not result.clips:
        raise BagError(f'{bag}: no clip of motion in {recording.topic} ({"; ".join(result.notes) or "no motion"})')
    for clip in result.clips:
        reason = limit_violation(clip.q, options.rate_hz) or shortness(
            len(clip), speedups, window_frames, options.rate_hz
        )
        if reason:
            raise BagError(f'{bag}: {reason}')
    return CheckedBag(
        bag=bag,
        label=label,
        rate_hz=rate_hz,
        clips=result.clips,
        source=f'{bag}:{recording.topic}',
        notes=list(recording.problems),
    )


def _check_bags(
    path: pathlib.Path, window_frames: int, speedups: tuple[int, ...], topic: str | None
) -> DemonstrationSet:
    search = find_bags([path])
    if not search.bags:
        reason = search.rejected[0][1] if search.rejected else 'no rosbag2 bag found'
        raise DemonstrationError([f'{path}: {reason}'])
    checked, problems = [], []
    for bag in search.bags:
        try:
            checked.append(check_bag(bag, window_frames=window_frames, speedups=speedups, topic=topic))
        except BagError as error:
            problems.append(one_line(error, max_chars=400))
    if problems:
        raise DemonstrationError(problems)
    return DemonstrationSet(path=path, window_frames=window_frames, speedups=speedups, bags=checked)


# ---------------------------------------------------------------------------------------------------
# A built dataset


def _bag_of_source(source: str) -> str:
    """The bag of a dataset clip's source '<bag directory>:<topic>' (a topic starts with '/')."""
    bag, separator, _topic = str(source).rpartition(':/')
    return bag if separator else str(source)


def _check_dataset(path: pathlib.Path, window_frames: int) -> DemonstrationSet:
    try:
        dataset = ReferenceDataset.load(path)
    except Exception as error:  # noqa: BLE001  any unreadable file is the same refusal
        raise DemonstrationError([f'{path}: not a dataset written by build_dataset ({one_line(error)})']) from None
    ur5 = default_joint_names()
    if tuple(dataset.joint_names) != ur5:
        raise DemonstrationError(
            [f"{path}: joints {', '.join(dataset.joint_names)} are not the UR5's ({', '.join(ur5)})"]
        )
    if not math.isclose(dataset.rate_hz, DEFAULT_RATE_HZ):
        raise DemonstrationError(
            [
                f"{path}: clips at {dataset.rate_hz:g} Hz, not the policy's {DEFAULT_RATE_HZ:g} Hz; "
                'build it again with build_dataset'
            ]
        )
    if dataset.num_clips == 0:
        raise DemonstrationError([f'{path}: the dataset holds no clip'])
    problems: dict[str, str] = {}  # bag -> its first problem
    for index in range(dataset.num_clips):
        bag = _bag_of_source(dataset.source[index])
        if bag in problems:
            continue
        label = str(dataset.label[index])
        clip = dataset.clip(index)
        factor = int(dataset.speed_factor[index])
        if label == UNLABELLED or not label:
            reason = f'unlabelled clips; label them {", ".join(KNOWN_LABELS)}'
        elif label not in KNOWN_LABELS:
            reason = f'unknown label {label!r}; the labels are {", ".join(KNOWN_LABELS)}'
        else:
            reason = limit_violation(clip.q, dataset.rate_hz)
            if reason is None and len(clip) < window_frames:
                reason = (
                    f"clip {index} (x{factor}) has {len(clip)} frames, fewer than the discriminator's window "
                    f'of {window_frames}'
                )
        if reason:
            problems[bag] = f'{path}: clips of {bag}: {reason}'
    if problems:
        raise DemonstrationError(list(problems.values()))
    speedups = tuple(sorted({int(k) for k in dataset.speed_factor if k != 1}))
    return DemonstrationSet(path=path, window_frames=window_frames, speedups=speedups, dataset=dataset)


# ---------------------------------------------------------------------------------------------------


def check_demonstrations(
    path: str | os.PathLike, *, window_frames: int, speedups: Sequence[int] = DEFAULT_SPEEDUPS, topic: str | None = None
) -> DemonstrationSet:
    """Check a folder of bags, one bag, or a dataset .npz (module docstring); raise DemonstrationError.

    window_frames: the discriminator's window (frames at 60 Hz); speedups: the factors the dataset
    will be built with (a clip must fill a window at the largest); topic: the JointState topic
    (None: each bag's only one)."""
    if window_frames < 1:
        raise ValueError(f'window_frames must be at least 1, got {window_frames}')
    path = pathlib.Path(path)
    if not path.exists():
        raise DemonstrationError([f'{path}: does not exist'])
    if path.is_file() and path.suffix == DATASET_SUFFIX:
        return _check_dataset(path, window_frames)
    return _check_bags(path, window_frames, tuple(speedups), topic)
