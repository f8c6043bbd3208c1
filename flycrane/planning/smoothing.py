"""Random shortcut smoothing (Geraerts & Overmars, IJRR 26(8), 2007) under the planner's
objective.

Each attempt picks two random points along the path (uniform in path length), joins them
by the straight local path, and keeps the shortcut if its motion, and the two segments the
cut leaves of the motions it cuts, are valid and it does not raise the objective's cost of
the replaced stretch (:mod:`flycrane.planning.objective`: for the cost-aware planners, the
mechanical work). Paths only get shorter; under mechanical work they never climb more.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from flycrane.errors import FieldProblem, InputError
from flycrane.planning.interfaces import Validity
from flycrane.planning.objective import OptimizationObjective
from flycrane.planning.result import TerminationCondition
from flycrane.planning.state_space import ConfigurationSpace


@dataclass(frozen=True)
class ShortcutConfig:
    """Parameters of random shortcut smoothing."""

    attempts: int = 100  #: shortcut attempts

    def __post_init__(self) -> None:
        if self.attempts < 0:
            raise InputError([FieldProblem("attempts", "must be >= 0")], "smoothing options")


def shortcut_path(
    path: NDArray[np.float64],
    space: ConfigurationSpace,
    validity: Validity,
    objective: OptimizationObjective,
    config: ShortcutConfig,
    seed: int = 0,
    termination: TerminationCondition | None = None,
) -> NDArray[np.float64]:
    """The path after ``config.attempts`` random shortcut attempts, shape (M', 9)."""
    path = np.array(path, dtype=float)
    rng = np.random.default_rng(seed)

    for _ in range(config.attempts):
        if len(path) < 3 or (termination is not None and termination() is not None):
            break
        cumulative = np.concatenate([[0.0], np.cumsum(space.distance(path[:-1], path[1:]))])
        s_a, s_b = np.sort(rng.uniform(0.0, cumulative[-1], 2))
        i, q_a = space.point_at_length(path, cumulative, s_a)
        j, q_b = space.point_at_length(path, cumulative, s_b)
        if i == j:
            continue  # both on one straight segment: nothing to shorten
        # The two cut segments are checked too: they lie on valid motions, but the checker
        # samples them at other points, between which a cut segment can graze an obstacle
        # (BENCHMARKS.md, "Planner v2, the default").
        if not (
            validity.motion_is_valid(q_a, q_b)
            and validity.motion_is_valid(path[i], q_a)
            and validity.motion_is_valid(q_b, path[j + 1])
        ):
            continue
        old = np.concatenate([q_a[None], path[i + 1 : j + 1], q_b[None]])
        added = objective.motion_cost(np.stack([q_a, q_b]))
        # Infinite: a sample between the motion check's own samples is infeasible; never
        # take such a shortcut (even where the replaced stretch's cost is infinite too).
        if not np.isfinite(added) or added > objective.motion_cost(old):
            continue
        path = np.concatenate([path[: i + 1], q_a[None], q_b[None], path[j + 1 :]])
    return space.without_repeats(path)
