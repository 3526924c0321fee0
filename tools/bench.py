#!/usr/bin/env python3
"""`make bench`: run every benchmarks/*.py and collect their Markdown sections into BENCHMARKS.md.

Each benchmark script measures one thing on this machine and prints a Markdown section (a `## ` title,
what was run and how, the figures). A failing script is reported in the file, the others still run.
"""

import argparse
import datetime
import os
import pathlib
import platform
import subprocess
import sys

ROOT = pathlib.Path(__file__).resolve().parent.parent


def machine_summary() -> str:
    """Cores, CPU model, Python and OS of this machine, on one line."""
    cpu = platform.processor() or 'unknown CPU'
    try:
        for line in open('/proc/cpuinfo'):
            if line.startswith('model name'):
                cpu = line.split(':', 1)[1].strip()
                break
    except OSError:
        pass
    return (
        f'{os.cpu_count()} cores ({cpu}), Python {platform.python_version()}, {platform.system()} {platform.release()}'
    )


def title_of(section: str) -> str:
    """A section's `## ` title line."""
    return section.splitlines()[0]


def split_sections(text: str) -> tuple[str, list[str]]:
    """A BENCHMARKS.md as its header and its `## ` sections."""
    header, _, body = text.partition('\n## ')
    return header.rstrip('\n') + '\n', (['## ' + s.strip() for s in body.split('\n## ')] if body else [])


def merge_sections(kept: list[str], fresh: list[str]) -> list[str]:
    """The kept sections with those of a fresh section's title replaced by it, in place; new titles last."""
    by_title = {title_of(s): s for s in fresh}
    merged = [by_title.pop(title_of(s), s) for s in kept]
    return merged + list(by_title.values())


def main() -> int:
    """Run the benchmarks and write their sections to --out."""
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument('--out', default='BENCHMARKS.md')
    parser.add_argument(
        'only',
        nargs='*',
        help='run only benchmarks whose file name contains one of these; '
        'their sections replace those of the same title in --out, the others are kept',
    )
    args = parser.parse_args()
    scripts = sorted((ROOT / 'benchmarks').glob('*.py'))
    if args.only:
        scripts = [s for s in scripts if any(o in s.name for o in args.only)]
    sections = []
    for script in scripts:
        print(f'[bench] {script.name} ...', flush=True)
        result = subprocess.run([sys.executable, str(script)], capture_output=True, text=True, cwd=ROOT)
        if result.returncode == 0:
            sections.append(result.stdout.strip())
        else:
            sections.append(
                f'## {script.stem}\n\nFAILED (exit {result.returncode}):\n\n```\n{result.stderr.strip()[-2000:]}\n```'
            )
        print(sections[-1], flush=True)
    today = datetime.date.today().isoformat()
    header = (
        f'# Benchmarks\n\nWritten by `make bench` on {today}: '
        f'{machine_summary()}.\nEach section says what it ran; figures are from that single run.\n'
    )
    out = ROOT / args.out
    if args.only and out.is_file():
        # A partial run replaces its own sections and keeps the others, saying which were re-run when.
        header, kept = split_sections(out.read_text())
        rerun = ', '.join(f'"{title_of(s)[3:]}"' for s in sections)
        header = header.rstrip('\n') + f'\nRe-run alone on {today} (`tools/bench.py {" ".join(args.only)}`): {rerun}.\n'
        sections = merge_sections(kept, sections)
    out.write_text(header + '\n' + '\n\n'.join(sections) + '\n')
    print(f'[bench] wrote {args.out}')
    return 0


if __name__ == '__main__':
    sys.exit(main())
