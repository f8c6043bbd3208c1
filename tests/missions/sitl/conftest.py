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
