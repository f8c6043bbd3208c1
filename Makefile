# Two entry points (README "Quick start"): `make run` and `make test`. Each creates the
# virtual environment on first use and reinstalls when pyproject.toml changes.
PYTHON ?= $(shell command -v python3.11 || command -v python3)
VENV ?= .venv
BIN := $(VENV)/bin

.PHONY: run test test-slow bench lint clean browser

$(BIN)/.installed: pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -e '.[test]'
	touch $@

# The main job on embedded defaults: plan the Rescue benchmark and export its missions.
run: $(BIN)/.installed
	$(BIN)/flycrane plan --out out/rescue

# Debian's Chromium for the viewer's browser tests (tests/service/test_viewer_browser.py),
# installed once where apt-get can run (as root, or through passwordless sudo). Where it
# cannot, this says so and the browser tests skip with the reason; nothing else depends on it.
CHROMIUM := /usr/bin/chromium
browser:
	@if [ ! -x $(CHROMIUM) ]; then \
	  if [ "$$(id -u)" = 0 ]; then sudo=""; \
	  elif command -v sudo >/dev/null && sudo -n true 2>/dev/null; then sudo="sudo -n"; \
	  else echo "make: cannot install chromium (not root, no passwordless sudo): browser tests will skip"; exit 0; fi; \
	  echo "make: installing Debian's chromium for the browser tests"; \
	  export DEBIAN_FRONTEND=noninteractive; \
	  { $$sudo apt-get install -y -qq chromium >/dev/null 2>&1 \
	    || { $$sudo apt-get update -qq && $$sudo apt-get install -y -qq chromium >/dev/null; }; } \
	  || echo "make: apt-get could not install chromium: browser tests will skip"; \
	fi

# The whole default test suite (CI runs exactly this through .ci/run): the static checks
# first (lint), then pytest.
test: lint browser
	$(BIN)/python -m pytest

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
