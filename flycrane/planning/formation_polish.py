"""Formation polish: raise a path's least thrust margin and headroom by reshaping the
formation a little at its waypoints, never lowering any of its least margins nor raising
its largest cost.

Why: Fig. 6's margins are bottlenecks, the least value along the path, which no
per-configuration cost sees. bitrrt's repair already weighs the margins the endpoints
bound (:mod:`flycrane.planning.algorithms.extension_kernel`), but a smoothed path's long legs
interpolate the formation between waypoints chosen for other poses, and its least margins
fall where the pose strains the cables most (the Puzzle's tilted passage, the Rescue's
yaw above the roofs).

The platform's poses are kept: the alphas are the formation's redundancy (design.md
section 3) and the platform's path, which carries the payload past the obstacles, stays
the same curve; only drones and cables move. Each pass visits the interior waypoints, the
one nearest the path's bottleneck first, and moves its alphas (Nelder-Mead in a box,
scipy) to maximize the soft minimum of the thrust margin plus that of the headroom
(h - m and f_hi - t_hi, in N: the two margins of Fig. 6 that grow with a more upright
formation, as the least slack does not) over the two local paths that meet there. A move
is kept when it raises that sum, both motions are valid (collision included), and the two
local paths keep every least margin (slack, headroom, thrust) at or above the whole path's
and their cost at or below the path's largest before the polish: the path's least margins
never drop and its maxC never rises.

What it may move, and why so little:

- only waypoints whose local paths come within ``band`` (0.1 N) of the path's least
  thrust margin or headroom: a reshaped formation is a manoeuvre the three drones must fly
  in step, and the average cost (avgC) rises with every move;
- each alpha at most ``reach`` (0.1 rad) from the planner's: unbounded, the polish takes
  alphas to the ends of their range and reshapes the formation inside a passage, which
  the drones fly out of step and into the obstacle (BENCHMARKS.md, "Planner v2, the
  default"). Even so, a polished formation can leave a drone a level leg slower than
  ArduCopter's ground-speed floor (an early leg), and such missions drift further apart
  in flight (the same section).

A soft minimum (-tau log sum exp(-t / tau)) rather than the minimum: where several
waypoints share a low-margin stretch, moving one of them cannot raise the stretch's hard
minimum, which its neighbours hold, but it raises the soft one, and the next pass moves the
neighbours. All margins are measured on the path discretized at the metrics resolution.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy.optimize import minimize

from flycrane.errors import FieldProblem, InputError
from flycrane.model.cable_system import CableSystem
from flycrane.model.statics_kernel import statics_margins
from flycrane.planning.interfaces import Validity
from flycrane.planning.metrics import METRICS_RESOLUTION
from flycrane.planning.result import TerminationCondition
from flycrane.planning.state_space import ConfigurationSpace


@dataclass(frozen=True)
class PolishConfig:
    """Parameters of the formation polish."""

    passes: int = 2  #: sweeps over the waypoints (a sweep that moves none ends the polish)
    evaluations: int = 40  #: Nelder-Mead evaluations per waypoint
    softness: float = 0.2  #: tau of the soft minimum [N]
    resolution: float = METRICS_RESOLUTION  #: sampling step of the local paths
    #: polish only where the two local paths at a waypoint come within this of the path's
    #: least thrust margin or headroom [N] (module docstring)
    band: float = 0.1
    #: how far each alpha may move from the planner's [rad] (module docstring)
    reach: float = 0.1

    def __post_init__(self) -> None:
        checks = [
            ("passes", self.passes >= 0, "must be >= 0"),
            ("evaluations", self.evaluations >= 1, "must be >= 1"),
            ("softness", self.softness > 0, "must be > 0"),
            ("resolution", self.resolution > 0, "must be > 0"),
            ("band", self.band >= 0, "must be >= 0"),
            ("reach", self.reach >= 0, "must be >= 0"),
        ]
        problems = [FieldProblem(name, why) for name, ok, why in checks if not ok]
        if problems:
            raise InputError(problems, "polish options")


@dataclass(frozen=True)
class _Margins:
    """Least margins and largest cost over a stretch of configurations [N]."""

    slack: float
    headroom: NDArray[np.float64]  #: (K,) per configuration
    thrust: NDArray[np.float64]  #: (K,) per configuration
    cost: float

    def objective(self, softness: float) -> float:
        """Soft minimum of the thrust margin plus that of the headroom [N]."""
        return _soft_minimum(self.thrust, softness) + _soft_minimum(self.headroom, softness)


def _soft_minimum(t: NDArray[np.float64], softness: float) -> float:
    low = t.min()
    return float(low - softness * np.log(np.exp(-(t - low) / softness).sum()))


def _margins(system: CableSystem, q: NDArray[np.float64]) -> _Margins:
    cost, margins = statics_margins(system, q)
    return _Margins(
        slack=float(margins[:, 0].min()),
        headroom=margins[:, 1],
        thrust=margins[:, 2],
        cost=float(cost.max()),
    )


def polish_formation(
    path: NDArray[np.float64],
    space: ConfigurationSpace,
    validity: Validity,
    system: CableSystem,
    config: PolishConfig,
    termination: TerminationCondition | None = None,
) -> NDArray[np.float64]:
    """The path with its waypoints' alphas moved to raise its least thrust margin and
    headroom (module docstring); same shape, same poses, same end points."""
    path = np.array(path, dtype=float)
    planned = path[:, 6:].copy()

    def whole() -> _Margins:
        return _margins(system, space.discretize_path(path, config.resolution))

    least = whole()
    if not np.isfinite(least.cost):
        return path  # an infeasible path has no margins to keep; nothing is polished
    highest_cost = least.cost

    def stretch(a: NDArray, q: NDArray, b: NDArray) -> _Margins:
        first = space.discretize(a, q, config.resolution)
        second = space.discretize(q, b, config.resolution)
        return _margins(system, np.concatenate([first, second[1:]]))

    def shortfall(m: _Margins) -> float:
        """How far a stretch falls below the path's least margins or above its largest
        cost: a move that keeps them (0) never lowers the path's least margins."""
        return (
            max(0.0, least.slack - m.slack)
            + max(0.0, least.headroom.min() - m.headroom.min())
            + max(0.0, least.thrust.min() - m.thrust.min())
            + max(0.0, np.log(m.cost / highest_cost))
        )

    for _ in range(config.passes):
        moved = False
        own = _margins(system, path)
        # Nearest the bottleneck first: the waypoint whose own margin, thrust or headroom,
        # is closest to the path's least of that margin.
        closeness = np.minimum(own.thrust - least.thrust.min(), own.headroom - least.headroom.min())
        for j in 1 + np.argsort(closeness[1:-1], kind="stable"):
            if termination is not None and termination() is not None:
                return path
            a, b = path[j - 1], path[j + 1]
            current = stretch(a, path[j], b)
            if (
                current.thrust.min() > least.thrust.min() + config.band
                and current.headroom.min() > least.headroom.min() + config.band
            ):
                continue

            low = np.maximum(space.alpha_low, planned[j] - config.reach)
            high = np.minimum(space.alpha_high, planned[j] + config.reach)

            def with_alphas(
                alphas: NDArray, j: int = j, low: NDArray = low, high: NDArray = high
            ) -> NDArray:
                q = path[j].copy()
                q[6:] = np.clip(alphas, low, high)
                return q

            def objective(alphas: NDArray, a: NDArray = a, b: NDArray = b) -> float:
                m = stretch(a, with_alphas(alphas), b)
                if not np.isfinite(m.cost):
                    return np.inf
                # An exact penalty: the optimum keeps the bounds where it can.
                return -m.objective(config.softness) + 100.0 * shortfall(m)

            found = minimize(
                objective,
                path[j, 6:],
                method="Nelder-Mead",
                bounds=list(zip(low, high, strict=True)),
                options={"maxfev": config.evaluations, "xatol": 1e-3},
            )
            q = with_alphas(found.x)
            new = stretch(a, q, b)
            # A gain of at least 1 mN, so that a sweep of rounding-level moves ends the polish.
            if (
                new.objective(config.softness) > current.objective(config.softness) + 1e-3
                and shortfall(new) == 0.0
                and validity.motion_is_valid(a, q)
                and validity.motion_is_valid(q, b)
            ):
                path[j] = q
                least = whole()
                moved = True
        if not moved:
            break
    return path
