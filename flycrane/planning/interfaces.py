"""What planners see: the validity roles and the planner role (OMPL's StateValidityChecker,
MotionValidator and Planner), as protocols so that planners, checkers and test doubles
plug together without importing each other."""

from __future__ import annotations

from collections.abc import Callable
from typing import Protocol

import numpy as np
from numpy.typing import NDArray

from flycrane.model.cable_system import CableSystem
from flycrane.planning.objective import OptimizationObjective
from flycrane.planning.result import PlannerResult, PlanningProgress, TerminationCondition
from flycrane.planning.validity_kernel import CompiledValidity


class Validity(Protocol):
    """What a planner needs to know about configurations."""

    def cost(self, q: NDArray[np.float64]) -> NDArray[np.float64]:
        """c(q) per configuration (N,), +inf where infeasible or out of bounds."""

    def is_valid(self, q: NDArray[np.float64]) -> NDArray[np.bool_]:
        """Feasible, in bounds and collision-free, per configuration (N,)."""

    def motion_is_valid(self, q_from: NDArray[np.float64], q_to: NDArray[np.float64]) -> bool:
        """Every configuration of the local path q_from -> q_to is valid."""

    def describe_invalid(self, q: NDArray[np.float64]) -> str:
        """Why a configuration (9,) is invalid, for messages."""


class CompiledChecker(Validity, Protocol):
    """A validity checker whose checks compiled planners can call without Python."""

    system: CableSystem  #: the system whose statics the checks use
    compiled: CompiledValidity
    work: tuple
    resolution: float
    #: The payload has meshes, which only :meth:`motion_is_valid` (fcl) checks.
    payload_meshes: bool


class Planner(Protocol):
    """A planner: solve() returns a status, never raises for "no path"."""

    name: str
    objective: OptimizationObjective  #: what it minimizes; smoothing keeps to it

    def solve(
        self,
        start: NDArray[np.float64],
        goal: NDArray[np.float64],
        termination: TerminationCondition,
        seed: int = 0,
        progress: Callable[[PlanningProgress], None] | None = None,
    ) -> PlannerResult: ...
