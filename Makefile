# Two entry points (README "Quick start"): `make run` and `make test`. Each creates the
# virtual environment on first use and reinstalls when pyproject.toml changes.
PYTHON ?= $(shell command -v python3.11 || command -v python3)
VENV ?= .venv
BIN := $(VENV)/bin

.PHONY: run test test-slow bench lint clean

$(BIN)/.installed: pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -e '.[test]'
	touch $@

# The main job on embedded defaults: plan the Rescue benchmark and export its missions.
run: $(BIN)/.installed
	$(BIN)/flycrane plan --out out/rescue

# The whole default test suite (CI runs exactly this through .ci/run).
test: $(BIN)/.installed
	$(BIN)/python -m pytest

# Long soak and statistical cases, kept out of the default run.
test-slow: $(BIN)/.installed
	$(BIN)/python -m pytest -m slow

bench: $(BIN)/.installed
	$(BIN)/python benchmarks/cost_throughput.py

lint: $(BIN)/.installed
	$(BIN)/python -m pip install --quiet ruff mypy
	$(BIN)/ruff check flycrane missions service tests benchmarks
	$(BIN)/mypy flycrane

clean:
	rm -rf $(VENV) .pytest_cache .hypothesis build *.egg-info
