#!/usr/bin/env python3
"""Drawn stroke styles for tuning and held-out demonstration sets (stylepong_sim/teaching/style_space.py).

  tools/drawn_styles.py generate --count N --seed S --out DIR
      N style files DIR/style_<k>.yaml (k = 0..N-1), each drawn until every take a recording drags passes
      stroke_styles' checks, and DIR/split.json: the seed, each style's parameters and refused draws, and the
      split into tuning and held-out styles (a seeded shuffle, half each), drawn once, here.
  tools/drawn_styles.py record --split DIR/split.json --which heldout|tuning --out SETS_DIR [--dry-run]
      each chosen style's seven clips into SETS_DIR/<style>/ through tools/record_demos.sh (the real
      pipeline), in demonstrations/README.md's swing order, at the style's tempo and 125 Hz joint states.
      A style whose folder already holds seven clips is skipped; --dry-run prints the commands only.

Run it with the workspace sourced (source ros2_ws/install/setup.bash). The same seed gives the same files.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import os
import pathlib
import shlex
import subprocess
import sys

import numpy as np
import yaml

from stylepong_sim.teaching import stroke_styles, style_space

ROOT = pathlib.Path(__file__).resolve().parent.parent
RECORD_DEMOS = ROOT / 'tools' / 'record_demos.sh'
JOINT_STATE_RATE_HZ = 125.0  # a CB3 UR driver's rate, as the hand-made sets were recorded
SPLIT_FILE = 'split.json'


def style_file_text(parameters: style_space.StyleParameters, seed: int, name: str) -> str:
    """The style file: its key poses, with a header saying where it came from and the tempo to record it at."""
    header = (
        f'# {name}: drawn by tools/drawn_styles.py generate --seed {seed} (stylepong_sim/teaching/style_space.py).\n'
        f'# Record at BACKSWING_S={parameters.backswing_s} FORWARD_SWING_S={parameters.forward_swing_s} '
        f'(split.json holds every parameter).\n'
    )
    return header + yaml.safe_dump(style_space.key_poses(parameters), sort_keys=False, default_flow_style=None)


def generate(count: int, seed: int, out: pathlib.Path) -> dict:
    """Write the style files and split.json into `out`; the split document."""
    # Two streams of the seed: the split does not change with how many draws the checks refused.
    draws, shuffle = np.random.default_rng([seed, 0]), np.random.default_rng([seed, 1])
    kinematics = stroke_styles.StrokeKinematics()
    out.mkdir(parents=True, exist_ok=True)
    styles = {}
    for k in range(count):
        name = f'style_{k}'
        checked = style_space.draw_checked_style(draws, kinematics)
        (out / f'{name}.yaml').write_text(style_file_text(checked.parameters, seed, name))
        styles[name] = {
            'file': f'{name}.yaml',
            'parameters': dataclasses.asdict(checked.parameters),
            'rejected_draws': list(checked.rejections),
        }
        print(f'[drawn_styles] {name}: passed after {len(checked.rejections)} refused draw(s)', flush=True)
    rejected = sum(len(style['rejected_draws']) for style in styles.values())
    split = {
        'seed': seed,
        'count': count,
        'draws': count + rejected,
        'rejected': rejected,
        **style_space.split_tuning_heldout(list(styles), shuffle),
        'styles': styles,
    }
    (out / SPLIT_FILE).write_text(json.dumps(split, indent=2) + '\n')
    print(
        f'[drawn_styles] {count} style(s) in {out}: {rejected} of {count + rejected} draws refused; '
        f'tuning {", ".join(split["tuning"]) or "-"}; held out {", ".join(split["heldout"]) or "-"}'
    )
    return split


def recorded_clips(folder: pathlib.Path) -> int:
    """How many bags a set's folder holds."""
    return len(list(folder.glob('*/metadata.yaml'))) if folder.is_dir() else 0


def record_command(split_path: pathlib.Path, name: str, sets_dir: pathlib.Path) -> tuple[list[str], dict[str, str]]:
    """tools/record_demos.sh's command line and environment for one style's seven clips."""
    split = json.loads(split_path.read_text())
    style = split['styles'][name]
    parameters = style_space.StyleParameters(**style['parameters'])
    environment = {
        'STROKES_FILE': str((split_path.parent / style['file']).resolve()),
        # Written with a decimal point: record_demos.sh passes them on as double parameters.
        'BACKSWING_S': f'{parameters.backswing_s:.2f}',
        'FORWARD_SWING_S': f'{parameters.forward_swing_s:.2f}',
        'JOINT_STATE_RATE_HZ': f'{JOINT_STATE_RATE_HZ:.1f}',
    }
    return [str(RECORD_DEMOS), '--out', str(sets_dir / name), *style_space.RECORDING_ORDER], environment


def record(split_path: pathlib.Path, which: str, sets_dir: pathlib.Path, dry_run: bool) -> int:
    """Record the chosen styles' sets one after the other; the first failing recording's exit code, else 0."""
    names = json.loads(split_path.read_text())[which]
    for name in names:
        command, environment = record_command(split_path, name, sets_dir)
        shown = ' '.join(f'{k}={v}' for k, v in environment.items()) + ' ' + shlex.join(command)
        clips = recorded_clips(sets_dir / name)
        if clips == len(style_space.RECORDING_ORDER):
            print(f'[drawn_styles] {name}: {sets_dir / name} holds its {clips} clips already; skipped')
            continue
        if clips:
            print(f'[drawn_styles] {name}: {sets_dir / name} holds {clips} clip(s) of 7; remove it to record again')
            return 2
        print(f'[drawn_styles] {name}: {shown}', flush=True)
        if not dry_run:
            result = subprocess.run(command, env={**os.environ, **environment}, check=False)
            if result.returncode:
                return result.returncode
    return 0


def main(argv: list[str] | None = None) -> int:
    """The command line (the module's docstring)."""
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    commands = parser.add_subparsers(dest='command', required=True)
    make = commands.add_parser('generate', help='draw N checked style files and split them')
    make.add_argument('--count', type=int, required=True)
    make.add_argument('--seed', type=int, required=True)
    make.add_argument('--out', type=pathlib.Path, required=True)
    take = commands.add_parser('record', help="record a split's tuning or held-out styles")
    take.add_argument('--split', type=pathlib.Path, required=True)
    take.add_argument('--which', choices=('heldout', 'tuning'), required=True)
    take.add_argument('--out', type=pathlib.Path, required=True)
    take.add_argument('--dry-run', action='store_true', help='print the commands, record nothing')
    args = parser.parse_args(argv)
    if args.command == 'generate':
        if args.count < 1 or args.seed < 0:
            parser.error('--count must be at least 1 and --seed not negative')
        generate(args.count, args.seed, args.out)
        return 0
    return record(args.split, args.which, args.out.resolve(), args.dry_run)


if __name__ == '__main__':
    sys.exit(main())
