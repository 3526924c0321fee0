"""Shipping: a chosen run's actor and records into `models/`, and a learned style's network into the skill
library (`models/skills/`), both written into the checkout."""

from __future__ import annotations

import argparse
import pathlib

from stylepong_policy.paths import MODELS


def shipping_parser(prog: str, description: str, run_help: str | None, name_help: str) -> argparse.ArgumentParser:
    """The command line both shipping commands start from: --run (the run directory), --name (what the
    shipped files are called) and --models-dir (the checkout's models folder, MODELS by default)."""
    parser = argparse.ArgumentParser(prog=prog, description=description)
    parser.add_argument('--run', required=True, type=pathlib.Path, help=run_help)
    parser.add_argument('--name', required=True, help=name_help)
    models_help = 'the models folder of the checkout (default: %(default)s)'
    parser.add_argument('--models-dir', type=pathlib.Path, default=MODELS, help=models_help)
    return parser
