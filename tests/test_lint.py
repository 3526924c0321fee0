"""The whole tree passes `ruff check` with the repository's ruff.toml: style is enforced by the tool."""
import importlib.util
import pathlib
import subprocess
import sys

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[1]


@pytest.mark.skipif(importlib.util.find_spec('ruff') is None,
                    reason='ruff is not installed (make setup installs it from requirements.lock)')
def test_ruff_check_passes_over_the_tree():
    result = subprocess.run([sys.executable, '-m', 'ruff', 'check', '--no-cache', '--output-format', 'concise', '.'],
                            cwd=ROOT, capture_output=True, text=True, timeout=120)
    assert result.returncode == 0, (
        f'ruff check found violations (fix them, or `python3 -m ruff check --fix .` for the mechanical ones):\n'
        f'{result.stdout}{result.stderr}')
