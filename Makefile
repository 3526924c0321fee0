# StylePong. Quick start: `make demo` (the main job) and `make test` (the whole suite).
# Both run `make setup` first; it is idempotent and quick when nothing changed.
SHELL := /bin/bash
ROOT := $(CURDIR)
# Sourcing the workspace is all a command needs: the venv underlay comes with it.
WS := set +u; source $(ROOT)/ros2_ws/install/setup.bash;
# Tests marked slow (over about 7 s each on a 2-core machine) run in .ci/run, which clears this.
PYTEST_ARGS ?= -m 'not slow'

# lint needs only the virtual environment (make setup made it), not the built workspace.
VENV := $(ROOT)/.venv/bin

.PHONY: setup demo test bench lint clean

setup:
	@$(ROOT)/tools/setup.sh

demo: setup
	@$(WS) $(ROOT)/tools/demo.sh

test: setup
	@$(WS) cd $(ROOT) && python3 -m pytest $(PYTEST_ARGS)

bench: setup
	@$(WS) cd $(ROOT) && python3 tools/bench.py --out BENCHMARKS.md

# The checks of .pre-commit-config.yaml, run from the venv over the whole tree without fetching the hooks'
# repositories (CI has no network): ruff check and ruff format --check (ruff.toml) and codespell (.codespellrc).
lint:
	@$(VENV)/python -c 'import ruff, codespell_lib' 2>/dev/null || { echo 'lint: no .venv with ruff and codespell: run make setup first' >&2; exit 2; }
	@cd $(ROOT) && $(VENV)/python -m ruff check . && $(VENV)/python -m ruff format --check . && $(VENV)/python -m codespell_lib && echo 'lint: ruff check, ruff format and codespell passed'

clean:
	rm -rf ros2_ws/build ros2_ws/install ros2_ws/log
