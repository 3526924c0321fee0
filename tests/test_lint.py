"""The whole tree passes `ruff check` and `ruff format --check` with the repository's ruff.toml, and codespell:
style is enforced by the tools."""

import importlib.util
import pathlib
import re
import subprocess
import sys

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[1]

needs_ruff = pytest.mark.skipif(
    importlib.util.find_spec('ruff') is None,
    reason='ruff is not installed (make setup installs it from requirements.lock)',
)


def run_over_the_tree(*args: str) -> subprocess.CompletedProcess:
    """`python -m <args>` in the repository's root (where ruff.toml and .codespellrc are read)."""
    return subprocess.run([sys.executable, '-m', *args], cwd=ROOT, capture_output=True, text=True, timeout=120)


@needs_ruff
def test_ruff_check_passes_over_the_tree():
    result = run_over_the_tree('ruff', 'check', '--no-cache', '--output-format', 'concise', '.')
    assert result.returncode == 0, (
        f'ruff check found violations (fix them, or `python3 -m ruff check --fix .` for the mechanical ones):\n'
        f'{result.stdout}{result.stderr}'
    )


@needs_ruff
def test_the_tree_is_formatted():
    result = run_over_the_tree('ruff', 'format', '--check', '--no-cache', '.')
    assert result.returncode == 0, (
        f'files not formatted (run `python3 -m ruff format .`):\n{result.stdout}{result.stderr}'
    )


@pytest.mark.skipif(
    importlib.util.find_spec('codespell_lib') is None,
    reason='codespell is not installed (make setup installs it from requirements.lock)',
)
def test_codespell_passes_over_the_tree():
    # The settings (what is skipped, the true words it would flag) are .codespellrc's, read from the root.
    result = run_over_the_tree('codespell_lib')
    assert result.returncode == 0, (
        f"codespell found misspellings (fix them; a true word goes in .codespellrc's ignore-words-list):\n"
        f'{result.stdout}{result.stderr}'
    )


def test_pre_commit_hooks_are_the_locked_versions():
    # The pre-commit hooks fetch their own copies of ruff and codespell: at other versions than the venv's, a
    # file could pass `make lint` and fail the hook, or the other way round.
    locked = dict(
        line.split('==')
        for line in (ROOT / 'requirements.lock').read_text().splitlines()
        if '==' in line and not line.startswith('#')
    )
    config = (ROOT / '.pre-commit-config.yaml').read_text()
    revs = dict(re.findall(r'repo: https://github\.com/[\w-]+/([\w-]+)\s+rev: v([\w.]+)', config))
    assert revs == {'ruff-pre-commit': locked['ruff'], 'codespell': locked['codespell']}, revs
