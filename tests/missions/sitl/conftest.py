"""The tasks the SITL tests fly, planned once per session with the ``sitl`` position-error
model (what these simulators were measured to do, BENCHMARKS.md)."""

from __future__ import annotations

from pathlib import Path

import pytest

from tests.missions.sitl.flights import plan


@pytest.fixture(scope="session")
def rescue(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return plan("rescue", 0, tmp_path_factory.mktemp("rescue"))


@pytest.fixture(scope="session")
def puzzle(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return plan("puzzle", 2, tmp_path_factory.mktemp("puzzle"))


@pytest.fixture(scope="session")
def puzzle_one_clearance(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The Puzzle kept at the model's one clearance (``mission.robust_clearance`` false):
    the plan the missions mode's in-step bound was set on. On the default, robust Puzzle
    plans the missions mode's pairs err beyond that bound, as each drone's own clock drifts
    (BENCHMARKS.md "Execution modes on the default plans")."""
    return plan("puzzle", 2, tmp_path_factory.mktemp("puzzle_one_clearance"), False)
