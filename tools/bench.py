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
    return (f'{os.cpu_count()} cores ({cpu}), Python {platform.python_version()}, '
            f'{platform.system()} {platform.release()}')


def main() -> int:
    """Run the benchmarks and write their sections to --out."""
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument('--out', default='BENCHMARKS.md')
    parser.add_argument('only', nargs='*', help='run only benchmarks whose file name contains one of these')
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
            sections.append(f'## {script.stem}\n\nFAILED (exit {result.returncode}):\n\n```\n'
                            f'{result.stderr.strip()[-2000:]}\n```')
        print(sections[-1], flush=True)
    header = (f'# Benchmarks\n\nWritten by `make bench` on {datetime.date.today().isoformat()}: '
              f'{machine_summary()}.\nEach section says what it ran; figures are from that single run.\n')
    (ROOT / args.out).write_text(header + '\n' + '\n\n'.join(sections) + '\n')
    print(f'[bench] wrote {args.out}')
    return 0


if __name__ == '__main__':
    sys.exit(main())
