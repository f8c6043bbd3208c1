"""Path quality metrics of the paper's Table I: avgC, maxC, MW, IC.

All are computed on the path discretized by the state space (its local paths cut into
pieces at most ``resolution`` long) (default 0.05, about 5 cm of drone travel;
every waypoint of the path is kept):

- avgC: the cost's mean along the path, IC over the path's length (the cost at its one
  configuration where it has no length); maxC: largest cost;
- MW (mechanical work, Jaillet et al. 2010): sum of the positive cost variations between
  consecutive samples;
- IC: integral of the cost along the path, trapezoidal in the path's length.

avgC is a mean in length, not over the samples: every local path is cut into whole
pieces, so a path of many short local paths (a refined one) has more samples per metre
than one of few long ones, and a mean over samples would weigh its stretches by how many
waypoints they hold.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import asdict, dataclass

import numpy as np
from numpy.typing import NDArray

from flycrane.planning.state_space import ConfigurationSpace

#: Default resampling step of the metrics [state-space distance].
METRICS_RESOLUTION = 0.05


def mechanical_work(costs: NDArray[np.float64]) -> float:
    """Sum of the positive cost variations along a sequence of costs; +inf if the sequence
    passes an infeasible configuration (cost +inf), where the climb is unbounded."""
    costs = np.asarray(costs, dtype=float)
    if not np.isfinite(costs).all():
        return float("inf")
    return float(np.clip(np.diff(costs), 0.0, None).sum())


@dataclass(frozen=True)
class PathMetrics:
    """Quality of one path (Table I columns) and its length."""

    length: float  #: state-space length
    avg_cost: float  #: avgC
    max_cost: float  #: maxC
    mechanical_work: float  #: MW
    cost_integral: float  #: IC
    samples: int  #: configurations evaluated

    def as_dict(self) -> dict[str, float]:
        return asdict(self)


def path_metrics(
    path: NDArray[np.float64],
    space: ConfigurationSpace,
    cost: Callable[[NDArray[np.float64]], NDArray[np.float64]],
    resolution: float = METRICS_RESOLUTION,
) -> PathMetrics:
    """avgC, maxC, MW and IC of a path under a cost function (module docstring)."""
    samples = space.discretize_path(path, resolution)
    costs = cost(samples)
    steps = space.distance(samples[:-1], samples[1:]) if len(samples) > 1 else np.zeros(0)
    length = float(steps.sum())
    # +inf through an infeasible configuration, also where a zero step meets it
    integral = (
        float(np.sum(0.5 * (costs[:-1] + costs[1:]) * steps))
        if np.isfinite(costs).all()
        else float("inf")
    )
    return PathMetrics(
        length=length,
        avg_cost=integral / length if length > 0.0 else float(costs.mean()),
        max_cost=float(costs.max()),
        mechanical_work=mechanical_work(costs),
        cost_integral=integral,
        samples=len(samples),
    )
