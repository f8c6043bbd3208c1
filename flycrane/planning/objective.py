"""What a planner optimizes: the cost of a state and of a motion (OMPL's
``OptimizationObjective`` role).

- :class:`MechanicalWork` (Jaillet, Cortés, Siméon 2010; OMPL's
  ``MechanicalWorkOptimizationObjective``): a state costs c(q) (design.md eq. 8), a motion
  the sum of its uphill cost changes. T-RRT, bitrrt and OMPL's TRRT minimize it.
- :class:`PathLength`: a state costs nothing, a motion its length in the state space's
  metric. RRT and RRTConnect are blind to the cost.

Each planner names its objective (``planner.objective``); smoothing keeps a shortcut only if
it does not raise the objective's cost of the stretch it replaces, and path metrics are
measured on the state cost.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Protocol

import numpy as np
from numpy.typing import NDArray

from flycrane.planning.metrics import METRICS_RESOLUTION, mechanical_work
from flycrane.planning.state_space import ConfigurationSpace


class OptimizationObjective(Protocol):
    """The cost of states and of motions a planner minimizes."""

    def state_cost(self, q: NDArray[np.float64]) -> NDArray[np.float64]:
        """Cost of each configuration (N,); +inf where infeasible."""

    def motion_cost(self, path: NDArray[np.float64]) -> float:
        """Cost of the motion along a path (M, 9) of local paths; +inf if it passes an
        infeasible configuration."""


@dataclass(frozen=True)
class MechanicalWork:
    """A motion costs the sum of its positive cost variations, sampled every
    ``resolution`` along its local paths (:func:`~flycrane.planning.metrics.mechanical_work`)."""

    cost: Callable[[NDArray[np.float64]], NDArray[np.float64]]  #: c(q)
    space: ConfigurationSpace
    resolution: float = METRICS_RESOLUTION

    def state_cost(self, q: NDArray[np.float64]) -> NDArray[np.float64]:
        return self.cost(q)

    def motion_cost(self, path: NDArray[np.float64]) -> float:
        return mechanical_work(self.cost(self.space.discretize_path(path, self.resolution)))


@dataclass(frozen=True)
class PathLength:
    """A motion costs its length in the state space's metric; every state costs 0."""

    space: ConfigurationSpace

    def state_cost(self, q: NDArray[np.float64]) -> NDArray[np.float64]:
        return np.zeros(len(np.atleast_2d(q)))

    def motion_cost(self, path: NDArray[np.float64]) -> float:
        path = np.asarray(path, dtype=float)
        return float(self.space.distance(path[:-1], path[1:]).sum()) if len(path) > 1 else 0.0
