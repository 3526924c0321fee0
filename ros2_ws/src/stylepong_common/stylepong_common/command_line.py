"""What the workspace's command-line tools share (no rclpy): how Ctrl-C ends them, their JSON summary and the
command line a result records."""

from __future__ import annotations

import argparse
import json
import pathlib
import shlex
import sys
from collections.abc import Callable, Sequence
from typing import NoReturn

from stylepong_common.exit_codes import EXIT_INTERRUPTED


def exit_with_run(
    program: str,
    run: Callable[[Sequence[str] | None], int],
    argv: Sequence[str] | None = None,
    on_interrupt: str = 'nothing written',
) -> NoReturn:
    """Exit with `run(argv)`'s status; Ctrl-C exits with EXIT_INTERRUPTED and one line saying what was kept."""
    try:
        code = run(argv)
    except KeyboardInterrupt:
        print(f'{program}: interrupted, {on_interrupt}', file=sys.stderr)
        code = EXIT_INTERRUPTED
    sys.exit(code)


def require_counts(parser: argparse.ArgumentParser, args: argparse.Namespace, names: Sequence[str]) -> None:
    """Stop with parser.error (exit status 2) at the first of these integer options below 1, named as typed."""
    for name in names:
        if getattr(args, name) < 1:
            parser.error(f'--{name.replace("_", "-")} must be at least 1')


def write_lines(path: pathlib.Path, lines: Sequence[str]) -> None:
    """Write a tool's text output (Markdown lines) to `path`, creating its folder, and say where."""
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text('\n'.join(lines) + '\n')
    print(f'wrote {path}')


def ros2_run_line(package: str, executable: str, argv: Sequence[str]) -> str:
    """`ros2 run PACKAGE EXECUTABLE ARGS...` as a person would type it again, quoted where a shell needs it."""
    return shlex.join(['ros2', 'run', package, executable, *argv])


def print_and_write_json(summary: dict, path: pathlib.Path | None) -> None:
    """Print a tool's summary as indented JSON and, when `path` is given, write the same text there."""
    text = json.dumps(summary, indent=2)
    print(text)
    if path is not None:
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(text + '\n')
