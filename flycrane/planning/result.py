"""What a planner returns: a status (not finding a path is an outcome, not an exception),
the path, and statistics (OMPL's PlannerStatus / PlannerData roles)."""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field
from enum import StrEnum

import numpy as np
from numpy.typing import NDArray


class PlannerStatus(StrEnum):
    """Outcome of one planning run."""

    EXACT_SOLUTION = "exact_solution"  #: a path from start to goal
    TIMEOUT = "timeout"  #: the time budget ran out
    CANCELLED = "cancelled"  #: stopped on request
    INVALID_START = "invalid_start"  #: start infeasible, in collision or out of bounds
    INVALID_GOAL = "invalid_goal"  #: goal infeasible, in collision or out of bounds

    @property
    def solved(self) -> bool:
        return self is PlannerStatus.EXACT_SOLUTION


@dataclass(frozen=True)
class PlannerStatistics:
    """Counters of one run. X (``expansion_attempts``) and N (``nodes``) as in Table I."""

    planner: str
    seed: int
    time: float  #: wall-clock seconds of solve()
    nodes: int  #: N: nodes in the tree(s)
    expansion_attempts: int  #: X: iterations of the main loop
    rejected_refinement: int = 0  #: expansions refused by refinementControl
    rejected_invalid: int = 0  #: extensions whose motion was invalid
    rejected_transition: int = 0  #: extensions refused by transitionTest
    final_temperature: float = float("nan")
    #: (expansion attempt, temperature) after each temperature change, decimated to <= 1000
    temperature_history: tuple[tuple[int, float], ...] = ()

    def as_dict(self) -> dict:
        data = {k: getattr(self, k) for k in self.__dataclass_fields__}
        data["temperature_history"] = [list(p) for p in self.temperature_history]
        if not np.isfinite(self.final_temperature):
            data["final_temperature"] = None
        return data


@dataclass(frozen=True)
class PlannerResult:
    """Status, path ((M, 9), empty unless solved) and statistics; ``reason`` says why not."""

    status: PlannerStatus
    path: NDArray[np.float64]
    statistics: PlannerStatistics
    reason: str = ""


@dataclass(frozen=True)
class PlanningProgress:
    """Periodic progress report for long runs (service, CLI)."""

    planner: str
    expansion_attempts: int
    nodes: int
    distance_to_goal: float  #: smallest distance of a tree node to the goal so far
    elapsed: float  #: seconds


@dataclass
class TerminationCondition:
    """Stop when the time budget is spent or ``should_stop()`` says so (OMPL's PTC role).

    ``should_stop`` is polled, so a cancel request (a flag, an event, a database row) stops
    the planner within one iteration.
    """

    time_budget: float
    should_stop: Callable[[], bool] | None = None
    started: float = field(default_factory=time.monotonic)

    def elapsed(self) -> float:
        return time.monotonic() - self.started

    def __call__(self) -> PlannerStatus | None:
        """None while planning may continue, else the status to stop with."""
        if self.should_stop is not None and self.should_stop():
            return PlannerStatus.CANCELLED
        if self.elapsed() >= self.time_budget:
            return PlannerStatus.TIMEOUT
        return None
