# Two entry points (README "Quick start"): `make run` and `make test`. Each creates the
# virtual environment on first use and reinstalls when pyproject.toml changes.
PYTHON ?= $(shell command -v python3.11 || command -v python3)
VENV ?= .venv
BIN := $(VENV)/bin

.PHONY: run test test-slow bench lint clean clean-kernels browser postgres

$(BIN)/.installed: pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -e '.[test]'
	@# Compile numba's kernels into its cache as part of the install (a minute or two on 2
	@# cores, BENCHMARKS.md "flycrane plan end to end"): one plan of the Rescue runs every
	@# kernel the main job needs (bitrrt's loop among them), one T-RRT run those T-RRT adds
	@# (the planner of scenes with meshes), so a user's first plan starts warm.
	$(BIN)/flycrane plan --out $(VENV)/compile-kernels > /dev/null
	$(BIN)/flycrane bench --scenes rescue --planners trrt --runs 1 --workers 1 \
	  --out $(VENV)/compile-kernels/trrt > /dev/null
	touch $@

# The main job on embedded defaults: plan the Rescue benchmark and export its missions.
run: $(BIN)/.installed
	$(BIN)/flycrane plan --out out/rescue

# Debian packages the tests need, installed once where apt-get can run (as root, or through
# passwordless sudo). Where they cannot be installed, this says so and the tests that need
# them skip with the reason; nothing else depends on them.
# $(call apt_install,PACKAGE,PROBE,WHAT SKIPS): install PACKAGE unless `ls PROBE` succeeds.
define apt_install
	@if ! ls $(2) >/dev/null 2>&1; then \
	  if [ "$$(id -u)" = 0 ]; then sudo=""; \
	  elif command -v sudo >/dev/null && sudo -n true 2>/dev/null; then sudo="sudo -n"; \
	  else echo "make: cannot install $(1) (not root, no passwordless sudo): $(3) will skip"; exit 0; fi; \
	  echo "make: installing Debian's $(1) for the tests"; \
	  export DEBIAN_FRONTEND=noninteractive; \
	  { $$sudo apt-get install -y -qq $(1) >/dev/null 2>&1 \
	    || { $$sudo apt-get update -qq && $$sudo apt-get install -y -qq $(1) >/dev/null; }; } \
	  || echo "make: apt-get could not install $(1): $(3) will skip"; \
	fi
endef

# Chromium for the viewer's browser tests (tests/service/test_viewer.py).
browser:
	$(call apt_install,chromium,/usr/bin/chromium,browser tests)

# PostgreSQL's server for the storage and service tests on PostgreSQL (tests/postgres.py
# starts a private one for the test session).
postgres:
	$(call apt_install,postgresql,/usr/lib/postgresql/*/bin/initdb,PostgreSQL tests)

# The whole default test suite (CI runs exactly this through .ci/run): the static checks
# first (lint), then pytest in two runs. The tests that do not fly run on three workers
# (pytest-xdist, each module on one worker so that its fixtures start once; three on two
# cores, since many of them wait on servers, subprocesses and a browser); the SITL flights
# then run one at a time, alone on the machine, because each keeps three simulators and the
# ground's executor busy on its two cores.
test: lint browser postgres
	$(BIN)/python -m pytest -n 3 --dist loadscope -m "not slow and not sitl"
	$(BIN)/python -m pytest -m "sitl and not slow"

# Long soak and statistical cases, kept out of the default run.
test-slow: $(BIN)/.installed
	$(BIN)/python -m pytest -m slow

bench: $(BIN)/.installed
	$(BIN)/python benchmarks/cost_throughput.py

# ruff and mypy are pinned test dependencies (pyproject.toml).
lint: $(BIN)/.installed
	$(BIN)/ruff check .
	$(BIN)/ruff format --check .
	$(BIN)/mypy flycrane missions service

clean:
	rm -rf $(VENV) .pytest_cache .hypothesis build *.egg-info

# numba's cache of compiled kernels (README "Limits": it is kept per source file, so a
# kernel's callers keep the old code of a kernel edited in another file until it is emptied).
clean-kernels:
	find flycrane missions -name '*.nbi' -delete -o -name '*.nbc' -delete
