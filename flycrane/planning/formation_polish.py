"""Formation polish: raise a path's least thrust margin by reshaping the formation at its
waypoints, never lowering its least tension margins nor raising its largest cost.

Why: the cost (eq. 8) multiplies twelve tension factors against three thrust factors, so a
planner that drives the cost down -- bitrrt repairs every new node's alphas towards the
least cost -- buys tension margin with thrust margin wherever the pose strains the cables:
on the Puzzle's tilted passage its paths came within 2.2 N of a drone's thrust limit (the
median over 100 seeds) where T-RRT's random formations kept 3.2 N (BENCHMARKS.md, "Planner
v2"). Fig. 6's margins are bottlenecks, the least value along the path, which no
per-configuration cost sees.

The platform's poses are kept: the alphas are the formation's redundancy (design.md
section 3) and the platform's path, which carries the payload past the obstacles, stays
the same curve; only drones and cables move. Each pass visits the interior waypoints, the
one of least thrust margin first, and moves its alphas (Nelder-Mead in the alpha box,
scipy) to maximize a soft minimum of the thrust margin over the two local paths that meet
there. Only waypoints whose local paths come within ``band`` of the path's least thrust
margin are moved: every change of the formation is a manoeuvre the three drones must fly
in step, so it is spent where the margin is the path's bottleneck (polishing every
waypoint failed 3 of 20 Rescue and Puzzle mission generations where the unpolished paths
passed; BENCHMARKS.md, "Formation polish"). A move is kept when it raises that soft minimum
and:

- does not lower the least thrust margin of those two local paths;
- keeps their least slack and headroom margins (t_lo - f_lo, f_hi - t_hi) at or above the
  whole path's before the polish, and their cost at or below the path's largest (so the
  path's least margins and maxC are never worse);
- both motions are valid (collision included).

A soft minimum (-tau log sum exp(-t / tau)) rather than the minimum: where several
waypoints share a low-margin stretch, moving one of them cannot raise the stretch's hard
minimum, which its neighbours hold, but it raises the soft one, and the next pass moves the
neighbours. All margins are measured on the path discretized at the metrics resolution.

The polish is asked for (``PlannerOptions.polish``), not the default: the formation it
reshapes in a narrow passage is flown less accurately; on three SITL autopilots 1-2 of 13
polished Puzzle missions per run put the long bar into the slab where none of the
unpolished ones did (BENCHMARKS.md, "Formation polish" and "Home height").
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy.optimize import minimize

from flycrane.cable_system import CableSystem
from flycrane.errors import FieldProblem, InputError
from flycrane.metrics import METRICS_RESOLUTION
from flycrane.planning.interfaces import Validity
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
    #: least thrust margin [N] (module docstring)
    band: float = 0.5

    def __post_init__(self) -> None:
        checks = [
            ("passes", self.passes >= 0, "must be >= 0"),
            ("evaluations", self.evaluations >= 1, "must be >= 1"),
            ("softness", self.softness > 0, "must be > 0"),
            ("resolution", self.resolution > 0, "must be > 0"),
            ("band", self.band >= 0, "must be >= 0"),
        ]
        problems = [FieldProblem(name, why) for name, ok, why in checks if not ok]
        if problems:
            raise InputError(problems, "polish options")


@dataclass(frozen=True)
class _Margins:
    """Least margins and largest cost over a stretch of configurations [N]."""

    slack: float
    headroom: float
    thrust: NDArray[np.float64]  #: (K,) per configuration
    cost: float

    def soft_thrust(self, softness: float) -> float:
        t = self.thrust
        low = t.min()
        return float(low - softness * np.log(np.exp(-(t - low) / softness).sum()))


def _margins(system: CableSystem, q: NDArray[np.float64]) -> _Margins:
    from flycrane.statics_kernel import compiled_statics  # numba import kept off the CLI path

    f0, v, m, cost = compiled_statics(system, q)
    return _Margins(
        slack=float((f0 - v - system.tension_min).min()),
        headroom=float((system.tension_max - f0 - v).min()),
        thrust=(system.max_thrusts - m).min(axis=1),
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
    """The path with its waypoints' alphas moved to raise its least thrust margin (module
    docstring); same shape, same poses, same end points."""
    path = np.array(path, dtype=float)
    low, high = space.alpha_low, space.alpha_high
    before = _margins(system, space.discretize_path(path, config.resolution))
    if not np.isfinite(before.cost):
        return path  # an infeasible path has no margins to keep; nothing is polished

    def stretch(a: NDArray, q: NDArray, b: NDArray) -> _Margins:
        first = space.discretize(a, q, config.resolution)
        second = space.discretize(q, b, config.resolution)
        return _margins(system, np.concatenate([first, second[1:]]))

    def keeps_bounds(m: _Margins) -> bool:
        return m.slack >= before.slack and m.headroom >= before.headroom and m.cost <= before.cost

    for _ in range(config.passes):
        moved = False
        own = _margins(system, path).thrust
        least = _margins(system, space.discretize_path(path, config.resolution)).thrust.min()
        for j in 1 + np.argsort(own[1:-1], kind="stable"):
            if termination is not None and termination() is not None:
                return path
            a, b = path[j - 1], path[j + 1]
            current = stretch(a, path[j], b)
            if current.thrust.min() > least + config.band:
                continue

            def with_alphas(alphas: NDArray, j: int = j) -> NDArray:
                q = path[j].copy()
                q[6:] = np.clip(alphas, low, high)
                return q

            def objective(alphas: NDArray, a: NDArray = a, b: NDArray = b) -> float:
                m = stretch(a, with_alphas(alphas), b)
                if not np.isfinite(m.cost):
                    return np.inf
                # Exact penalties: the optimum keeps the bounds where it can.
                shortfall = (
                    max(0.0, before.slack - m.slack)
                    + max(0.0, before.headroom - m.headroom)
                    + max(0.0, np.log(m.cost / before.cost))
                )
                return -m.soft_thrust(config.softness) + 100.0 * shortfall

            found = minimize(
                objective,
                path[j, 6:],
                method="Nelder-Mead",
                bounds=[(low, high)] * 3,
                options={"maxfev": config.evaluations, "xatol": 1e-3},
            )
            q = with_alphas(found.x)
            new = stretch(a, q, b)
            # A gain of at least 1 mN, so that a sweep of rounding-level moves ends the polish.
            if (
                new.soft_thrust(config.softness) > current.soft_thrust(config.softness) + 1e-3
                and new.thrust.min() >= current.thrust.min()
                and keeps_bounds(new)
                and validity.motion_is_valid(a, q)
                and validity.motion_is_valid(q, b)
            ):
                path[j] = q
                moved = True
        if not moved:
            break
    return path
