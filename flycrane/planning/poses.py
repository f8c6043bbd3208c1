"""Configurations from platform poses: the alphas of least cost (with a valid result).

A user may give a start or goal as a platform pose only (position and tilt-and-torsion
angles); the drones' alphas are then free. We take, among a grid of alpha triples over the
scene's alpha range, the valid configuration of least cost: the grid's cost is one compiled
batch (15^3 = 3375 configurations, a few milliseconds), and validity (collisions) is checked
in increasing order of cost until one passes (and, where the caller asks, passes its own
test too: a pose on a surface must also rise clear of it within the plan's clearance).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from numpy.typing import ArrayLike, NDArray

from flycrane.planning.state_space import ConfigurationSpace
from flycrane.planning.validity import InvalidConfigurationError, ValidityChecker

#: Alpha grid points per drone.
ALPHA_GRID = 15
#: Most valid candidates put to a caller's ``accept``, in increasing order of cost.
MOST_ACCEPTS = 64


def configuration_from_pose(
    space: ConfigurationSpace,
    validity: ValidityChecker,
    position: ArrayLike,
    orientation: ArrayLike,
    what: str = "pose",
    accept: Callable[[NDArray[np.float64]], bool] | None = None,
) -> NDArray[np.float64]:
    """The least-cost valid configuration (9,) with the given platform pose; with
    ``accept``, the least-cost valid one it accepts among the first :data:`MOST_ACCEPTS`
    valid ones (a caller's further test, such as a pose on a surface that must also rise
    clear of it), else the least-cost valid one.

    Raises
    ------
    InvalidConfigurationError
        If no alpha triple of the grid gives a valid configuration; the reasons are those of
        the least-cost candidate.
    """
    alphas = np.linspace(space.alpha_low, space.alpha_high, ALPHA_GRID)
    grid = np.stack(np.meshgrid(alphas, alphas, alphas, indexing="ij"), axis=-1).reshape(-1, 3)
    pose = np.concatenate([np.asarray(position, float), np.asarray(orientation, float)])
    candidates = np.concatenate([np.broadcast_to(pose, (len(grid), 6)), grid], axis=1)
    cost = validity.cost(candidates)
    order = np.argsort(cost)
    finite = order[np.isfinite(cost[order])]
    first, tried = None, 0
    for start in range(0, len(finite), 64):
        batch = candidates[finite[start : start + 64]]
        for q in batch[validity.is_valid(batch)]:
            if accept is None or accept(q):
                return q
            first = q if first is None else first
            tried += 1
            if tried == MOST_ACCEPTS:
                return first
    if first is not None:
        return first
    raise InvalidConfigurationError(what, validity.explain(candidates[order[0]]))
