# StylePong. Quick start: `make demo` (the main job) and `make test` (the whole suite).
# Both run `make setup` first; it is idempotent and quick when nothing changed.
SHELL := /bin/bash
ROOT := $(CURDIR)
# Sourcing the workspace is all a command needs: the venv underlay comes with it.
WS := set +u; source $(ROOT)/ros2_ws/install/setup.bash;
# Tests marked slow (over 20 s each on a 2-core machine) run in .ci/run, which clears this.
PYTEST_ARGS ?= -m 'not slow'

.PHONY: setup demo test bench clean

setup:
	@$(ROOT)/tools/setup.sh

demo: setup
	@$(WS) $(ROOT)/tools/demo.sh

test: setup
	@$(WS) cd $(ROOT) && python3 -m pytest $(PYTEST_ARGS)

bench: setup
	@$(WS) cd $(ROOT) && python3 tools/bench.py --out BENCHMARKS.md

clean:
	rm -rf ros2_ws/build ros2_ws/install ros2_ws/log
