"""How demonstration sets differ: per set its clips' lengths and peak joint speed, and the mean DTW
between every two sets' clips of the same label.

    ros2 run stylepong_policy build_dataset demonstrations/long -o /tmp/long.npz     (once per set)
    ros2 run stylepong_policy compare_demo_sets /tmp/shipped.npz /tmp/long.npz /tmp/compact.npz

Reads the datasets' original clips (speed factor 1, 60 Hz). Peak joint speed is style_metrics.smoothness's
(finite differences of the 60 Hz positions); DTW is style_metrics.dtw_distance_rad (summed Euclidean cost
over all six joints, unnormalised: it grows with the clips' length). A set against itself averages
over its distinct pairs of clips, which says how far one take of that style is from another.
"""

from __future__ import annotations

import argparse
import itertools
import pathlib
import sys

import numpy as np

from stylepong_description.robot_cell import STROKE_LABELS as LABELS
from stylepong_policy.evaluation.style_metrics import dtw_distance_rad, smoothness
from stylepong_policy.training.dataset import ReferenceDataset


def original_clips(dataset: ReferenceDataset) -> list[tuple[str, np.ndarray]]:
    """(label, joint positions) of every clip as recorded (speed factor 1)."""
    return [(str(dataset.label[i]), dataset.clip(int(i)).q) for i in dataset.select(speed_factors=[1])]


def mean_dtw_rad(a: list[np.ndarray], b: list[np.ndarray], same_set: bool) -> float:
    """Mean DTW over pairs (one clip of each; within a set, each distinct pair once); nan without pairs."""
    pairs = itertools.combinations(a, 2) if same_set else itertools.product(a, b)
    distances = [dtw_distance_rad(x, y) for x, y in pairs]
    return float(np.mean(distances)) if distances else float('nan')


def main(argv: list[str] | None = None) -> int:
    """Print the two tables (markdown) for the datasets given; 2 when one cannot be read."""
    parser = argparse.ArgumentParser(prog='compare_demo_sets', description=__doc__.splitlines()[0])
    parser.add_argument('datasets', nargs='+', type=pathlib.Path, help='build_dataset .npz files, one per set')
    args = parser.parse_args(argv)
    sets = {}
    for path in args.datasets:
        try:
            dataset = ReferenceDataset.load(path)
        except (OSError, KeyError, ValueError) as error:
            print(f'compare_demo_sets: {path}: not a dataset ({error})', file=sys.stderr)
            return 2
        sets[path.stem] = (original_clips(dataset), dataset.rate_hz)
    print('| set | clips (F/L/R) | clip lengths (s) | peak joint speed per clip (rad/s) | max |')
    print('|---|---|---|---|---|')
    for name, (clips, rate_hz) in sets.items():
        counts = '/'.join(str(sum(label == k for label, _ in clips)) for k in LABELS)
        lengths = ', '.join(f'{len(q) / rate_hz:.2f}' for _, q in clips)
        peaks = [smoothness(q, rate_hz).peak_joint_speed_rad_s for _, q in clips]
        print(f'| {name} | {counts} | {lengths} | {", ".join(f"{p:.2f}" for p in peaks)} | {max(peaks):.2f} |')
    print('\nMean DTW (rad) between the clips of the same label:\n')
    print('| set | set | forward | leftward | rightward | mean |')
    print('|---|---|---|---|---|---|')
    for a, b in itertools.combinations_with_replacement(sets, 2):
        row = [
            mean_dtw_rad(
                [q for k, q in sets[a][0] if k == label], [q for k, q in sets[b][0] if k == label], same_set=a == b
            )
            for label in LABELS
        ]
        known = [d for d in row if not np.isnan(d)]  # a label a set lacks (or has once, within a set) has none
        mean = f'{np.mean(known):.1f}' if known else '-'
        print(f'| {a} | {b} | ' + ' | '.join('-' if np.isnan(d) else f'{d:.1f}' for d in row) + f' | {mean} |')
    return 0


if __name__ == '__main__':
    sys.exit(main())
