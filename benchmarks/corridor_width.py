"""The least corridor width at which the formation fits, and the cost there (issue 12, item 2).

    python benchmarks/corridor_width.py [--seeds 0 1] [--search 1000000]

Question: over every configuration that is statically feasible (finite cost c(q), i.e.
wrench- and thrust-feasible, design.md s.5, default system carrying the corridor's crate)
and free of self-collision, with the tilt and alphas in the corridor scene's bounds and any
heading, what is the least width across the corridor (world y) of the collision bodies
(:mod:`flycrane.world.extent`), and what does it cost to fit a given width?

Method. The width does not depend on the position, so P stays at (0, 0, Z_CLEAR), clear of
the ground, and scipy's differential evolution searches (phi, theta, sigma, alpha1..3).
Validity is the project's checker in the corridor scene without its walls (bounds, statics
and self-collision, compiled). Each search is then polished by SLSQP on its smooth pieces:

- least width: minimize the width subject to the 15 margins of eq. 8 >= 0. At the minimum
  some margins are exactly 0, so c = +inf there: w* is an infimum, approached only at a
  cost that grows without bound (the curve c*(w) says how fast);
- least cost at width w, c*(w): minimize log c subject to width <= w; the polish is kept
  only if the checker finds it valid, no wider than w and cheaper.

Verification, with the checker (python-fcl and the compiled kernel) instead of the width
function: every point of c*(w) centred in a corridor 1 mm wider than w; the corridor scene
with its walls moved to a gap of w* +/- 1 cm, with the narrowest configuration found and
the c*(w* + 0.5 cm) one centred in it, a random search (uniform in the corridor, and around
the latter) counting valid configurations, and a differential evolution that maximizes the
wall clearance by fcl over feasible, self-collision-free configurations (x = 0, any y),
whose best is (gap - w*) / 2 if the width function is right. Last, the start formation's
width at every heading against the checker.
"""

from __future__ import annotations

import argparse
import math
import subprocess
import time
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy.optimize import differential_evolution, minimize

from flycrane.model.cost import cost_margin_factors
from flycrane.model.statics import evaluate_statics
from flycrane.planning.problem import PlanningProblem
from flycrane.planning.validity import ValidityChecker
from flycrane.world.extent import extent_from_configuration, width_from_configuration
from flycrane.world.scene import Box, SceneSpec

Z_CLEAR = 5.0  #: height of P [m]: the crate's bottom and every drone well above the ground
WALLS = ("north wall", "south wall")  #: corridor.toml's obstacles
#: Objective of configurations that fit no corridor of the asked width, and of invalid ones:
#: above every finite log c (at most log(1.8e308) = 709.8), so any fitting valid
#: configuration beats them; the width excess orders the former.
TOO_WIDE, INVALID = 1.0e3, 1.0e4


@dataclass(frozen=True)
class Fit:
    """A configuration (9,), its width across the corridor [m] and its cost c(q)."""

    q: NDArray[np.float64]
    width: float
    cost: float


class WidthSearch:
    """Searches over (phi, theta, sigma, alpha1..3) of the corridor's formation."""

    def __init__(self, problem: PlanningProblem) -> None:
        self.problem = problem
        self.system, self.scene = problem.system, problem.scene
        self.free = problem.validity.without(WALLS)  # statics, self-collision, bounds
        b = self.scene.bounds
        self.bounds = [
            (-math.pi, math.pi),
            (0.0, b.max_tilt),
            (b.sigma_low, b.sigma_high),
            *[(b.alpha_low, b.alpha_high)] * 3,
        ]

    def configurations(self, v: NDArray[np.float64]) -> NDArray[np.float64]:
        """(N, 6) or (6,) search variables -> (N, 9) configurations at P = (0, 0, Z_CLEAR)."""
        v = np.atleast_2d(v)
        n = len(v)
        return np.column_stack([np.zeros(n), np.zeros(n), np.full(n, Z_CLEAR), v])

    def width(self, v: NDArray[np.float64]) -> NDArray[np.float64]:
        return width_from_configuration(self.system, self.scene, self.configurations(v))

    def fit(self, v: NDArray[np.float64]) -> Fit:
        q = self.configurations(v)
        cost, valid = self.free.cost_and_validity(q)
        return Fit(q[0], float(self.width(v)[0]), float(cost[0]) if valid[0] else math.inf)

    def margins(self, v: NDArray[np.float64]) -> NDArray[np.float64]:
        report = evaluate_statics(self.system, self.configurations(v))
        return cost_margin_factors(self.system, report)[0]

    def _evolve(self, objective, seed: int) -> NDArray[np.float64]:
        # Population 60 x 6 and 600 generations: seeds 0, 1 and 2 ended within 0.3 mm of each
        # other on w* before the polish; main() runs two seeds and keeps the better.
        # polish=False: scipy's polish (L-BFGS-B) assumes a smooth objective, ours steps.
        result = differential_evolution(
            objective,
            self.bounds,
            seed=seed,
            popsize=60,
            maxiter=600,
            tol=1e-10,
            vectorized=True,
            updating="deferred",
            polish=False,
        )
        return result.x

    def least_width(self, seed: int) -> tuple[Fit, Fit]:
        """(found, limit): the narrowest valid configuration the evolution found, and the
        SLSQP limit on the statics boundary (margins >= 0, so its cost is +inf)."""

        def objective(vt: NDArray[np.float64]) -> NDArray[np.float64]:
            q = self.configurations(vt.T)
            valid = self.free.is_valid(q)
            return self.width(vt.T) + np.where(valid, 0.0, INVALID)

        found = self.fit(self._evolve(objective, seed))
        limit = minimize(
            lambda v: self.width(v)[0],
            found.q[3:],
            method="SLSQP",
            bounds=self.bounds,
            constraints=[{"type": "ineq", "fun": self.margins}],
            options={"ftol": 1e-12, "maxiter": 500},
        )
        polished = self.fit(limit.x)
        if not (limit.success and polished.width <= found.width):
            return found, found
        return found, polished

    def least_cost(self, width: float, seed: int) -> Fit:
        """The least-cost valid configuration no wider than ``width`` [m]; cost +inf if
        none was found."""

        def objective(vt: NDArray[np.float64]) -> NDArray[np.float64]:
            q = self.configurations(vt.T)
            cost, valid = self.free.cost_and_validity(q)
            excess = np.maximum(self.width(vt.T) - width, 0.0)
            with np.errstate(divide="ignore"):
                log_cost = np.log(cost)
            fitting = np.where(excess > 0.0, TOO_WIDE + excess, log_cost)
            return np.where(valid, fitting, INVALID)

        best = self.fit(self._evolve(objective, seed))
        if best.width > width:
            return Fit(best.q, best.width, math.inf)

        def log_cost(v: NDArray[np.float64]) -> float:
            cost = self.free.cost(self.configurations(v))[0]
            return float(np.log(cost)) if np.isfinite(cost) else TOO_WIDE

        polish = minimize(
            log_cost,
            best.q[3:],
            method="SLSQP",
            bounds=self.bounds,
            constraints=[{"type": "ineq", "fun": lambda v: width - self.width(v)}],
            options={"ftol": 1e-12, "maxiter": 500},
        )
        polished = self.fit(polish.x)
        if polished.width <= width and polished.cost < best.cost:
            return polished
        return best


# -- the corridor and the checker's evidence -------------------------------------------------


def corridor_gap(scene: SceneSpec) -> float:
    """Gap between the scene's two walls [m] (inner faces, across world y)."""
    faces = [abs(o.center[1]) - o.size[1] / 2 for o in scene.obstacles if isinstance(o, Box)]
    return 2.0 * min(faces)


def corridor_with_gap(scene: SceneSpec, gap: float) -> SceneSpec:
    """The corridor scene with its walls (all its obstacles) moved, same sizes, to leave
    ``gap`` [m] centred on y = 0."""
    walls = tuple(
        o.model_copy(
            update={
                "center": (
                    o.center[0],
                    math.copysign(gap / 2 + o.size[1] / 2, o.center[1]),
                    o.center[2],
                )
            }
        )
        for o in scene.obstacles
    )
    return scene.model_copy(update={"obstacles": walls})


def centred(problem: PlanningProblem, q: NDArray[np.float64]) -> NDArray[np.float64]:
    """Configurations (N, 9) moved in y so their bodies' extent is centred on the corridor."""
    q = np.array(q, dtype=float, ndmin=2)
    extent = extent_from_configuration(problem.system, problem.scene, q)
    q[:, 1] -= extent.mean(axis=1)
    return q


def wall_clearance(checker: ValidityChecker, q: NDArray[np.float64]) -> float:
    """Distance [m] from the robot's bodies to the nearest wall by fcl (9,), or minus the
    deepest penetration of a wall where they touch: fcl's signed distance is wrong under
    penetration for the platform's mesh (-1.000 m for a contact 0.7 mm deep, measured)."""
    depths = [c.depth for c in checker.collision.contacts(q) if c.other in WALLS]
    if depths:
        return -max(depths)
    return checker.collision.closest(q).distance


def best_clearance(
    checker: ValidityChecker, free: ValidityChecker, x0: NDArray[np.float64], seed: int
) -> tuple[float, float, int]:
    """:func:`wall_clearance` maximized by differential evolution over feasible,
    self-collision-free configurations (y, phi, theta, sigma, alpha1..3) at x = 0,
    z = Z_CLEAR, with x0 (7,) in the first population.

    Returns
    -------
    (clearance of x0 [m], largest clearance found [m], configurations evaluated)
    """
    b = checker.scene.bounds

    def objective(v: NDArray[np.float64]) -> float:
        q = np.r_[0.0, v[0], Z_CLEAR, v[1:]]
        if not free.is_valid(q)[0]:
            return 1.0  # worse than any clearance in a corridor narrower than 2 m
        return -wall_clearance(checker, q)

    result = differential_evolution(
        objective,
        [(-0.5, 0.5), (-math.pi, math.pi), (0.0, b.max_tilt), (b.sigma_low, b.sigma_high)]
        + [(b.alpha_low, b.alpha_high)] * 3,
        seed=seed,
        x0=x0,
        popsize=15,
        maxiter=100,
        tol=1e-12,
        polish=False,
    )
    return -objective(x0), -float(result.fun), int(result.nfev)


def search_counts(
    problem: PlanningProblem, checker: ValidityChecker, around: NDArray, n: int, seed: int
) -> tuple[int, int]:
    """Valid configurations (by the checker) among n uniform in the corridor's middle
    (x in [-2, 2], y across the gap, z in [3, 7], orientation and alphas uniform in the
    bounds) and among n Gaussian perturbations of ``around`` (9,) (2 mm in y, 0.005 rad in
    each angle: the fitting configurations near w* lie within millimetres of it)."""
    rng = np.random.default_rng(seed)
    gap = corridor_gap(checker.scene)
    uniform = problem.space.sample_uniform(rng, n)
    uniform[:, :3] = rng.uniform([-2.0, -gap / 2, 3.0], [2.0, gap / 2, 7.0], (n, 3))
    near = around + rng.normal(0.0, [0, 0.002, 0, *[0.005] * 6], (n, 9))
    near[:, 4] = np.abs(near[:, 4])  # a negative tilt is the same pose at phi + pi
    return int(checker.is_valid(uniform).sum()), int(checker.is_valid(near).sum())


# -- report ----------------------------------------------------------------------------------


def show(label: str, fit: Fit) -> None:
    q = ", ".join(f"{v:.4f}" for v in fit.q)
    print(f"{label}: width {fit.width:.4f} m, cost {fit.cost:.3e}, q = ({q})")


def verify(
    problem: PlanningProblem, search: WidthSearch, w_star: float, fits: dict[str, Fit], n: int
) -> None:
    """Print the checker's evidence in corridors of w* +/- 1 cm (module docstring)."""
    narrowest = centred(problem, fits["narrowest"].q)[0]
    for sign in (+1, -1):
        scene = corridor_with_gap(problem.scene, w_star + sign * 0.01)
        checker = PlanningProblem.from_scene(scene).validity
        print(f"gap {corridor_gap(scene):.4f} m:")
        for name, fit in fits.items():
            q = centred(problem, fit.q)[0]
            valid = bool(checker.is_valid(q)[0])
            why = "" if valid else f" ({checker.describe_invalid(q)})"
            print(f"  {name} (width {fit.width:.4f} m) centred: valid {valid}{why}")
        around = centred(problem, fits["c*(w* + 0.5 cm)"].q)[0]
        uniform, near = search_counts(problem, checker, around, n, seed=7)
        print(
            f"  random search: {uniform} valid of {n:,} uniform in the corridor, "
            f"{near} valid of {n:,} around c*(w* + 0.5 cm)"
        )
        seeded, best, evaluated = best_clearance(
            checker, search.free, np.r_[narrowest[1], narrowest[3:]], 3
        )
        print(
            f"  differential evolution ({evaluated:,} configurations, seeded with the narrowest) "
            f"on fcl wall clearance: best {100 * best:+.3f} cm, seed {100 * seeded:+.3f} cm, "
            f"(gap - w*) / 2 = {100 * sign * 0.005:+.3f} cm"
        )


def check_start(problem: PlanningProblem, search: WidthSearch) -> None:
    """The start formation's width at 360 headings, each against the checker in corridors
    2 cm wider and 2 cm narrower than it."""
    sigma = np.linspace(0.0, 2 * np.pi, 360, endpoint=False)
    starts = np.tile(np.r_[0.0, 0.0, Z_CLEAR, problem.start[3:]], (len(sigma), 1))
    starts[:, 5] = np.angle(np.exp(1j * sigma))
    widths = width_from_configuration(problem.system, problem.scene, starts)
    print(
        f"width {widths.min():.4f}-{widths.max():.4f} m over 360 headings (least at "
        f"sigma = {sigma[widths.argmin()]:.4f} rad, most at {sigma[widths.argmax()]:.4f}); "
        f"cost {search.free.cost(starts[0])[0]:.3e}"
    )
    agree = 0
    for q, w in zip(centred(problem, starts), widths, strict=True):
        wide = PlanningProblem.from_scene(corridor_with_gap(problem.scene, w + 0.02)).validity
        tight = PlanningProblem.from_scene(corridor_with_gap(problem.scene, w - 0.02)).validity
        agree += bool(wide.is_valid(q)[0]) and not bool(tight.is_valid(q)[0])
    print(f"checker: valid in width + 2 cm and invalid in width - 2 cm at {agree}/360 headings")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--seeds", type=int, nargs="+", default=[0, 1])
    parser.add_argument("--search", type=int, default=1_000_000, help="random samples per set")
    parser.add_argument(
        "--widths",
        type=float,
        nargs="+",
        default=[1.65, 1.7, 1.8, 1.9, 2.0, 2.2, 2.4, 2.8, 3.1],
        help="widths of the curve c*(w) [m], besides w* + 0.5 / 1 cm and the shipped gap",
    )
    args = parser.parse_args()
    started = time.perf_counter()
    problem = PlanningProblem.named("corridor")
    search = WidthSearch(problem)
    gap = corridor_gap(problem.scene)
    print(f"corridor.toml: walls {gap:.4f} m apart (inner faces at y = +/-{gap / 2:.4f} m)")

    print("\n== least width (differential evolution, then SLSQP on the margins) ==")
    results = [search.least_width(seed) for seed in args.seeds]
    for seed, (found, limit) in zip(args.seeds, results, strict=True):
        show(f"seed {seed} found", found)
        show(f"seed {seed} limit", limit)
    narrowest = min((r[0] for r in results), key=lambda f: f.width)
    w_star = min(r[1].width for r in results)
    limit = min((r[1] for r in results), key=lambda f: f.width)
    margins = search.margins(limit.q[3:])
    print(f"w* = {w_star:.4f} m; eq. 8 margins at the limit (thrust x3, slack x6, overload x6):")
    print("  " + " ".join(f"{m:.3g}" for m in margins))

    print("\n== least cost at which the formation fits a width: c*(w) ==")
    near = [round(w_star + 0.005, 4), round(w_star + 0.01, 4)]
    curve = {}
    for w in sorted({*args.widths, *near, gap}):
        fits = [search.least_cost(w, seed) for seed in args.seeds]
        curve[w] = min(fits, key=lambda f: f.cost)
        show(f"w <= {w:.4f} (seeds {' '.join(f'{f.cost:.3e}' for f in fits)})", curve[w])
        # The checker's word on it: valid in a corridor 1 mm wider than w.
        checker = PlanningProblem.from_scene(corridor_with_gap(problem.scene, w + 1e-3)).validity
        valid = checker.is_valid(centred(problem, curve[w].q))[0]
        print(f"  centred in a {w + 1e-3:.4f} m corridor: valid {valid}")

    print("\n== the checker in the corridor with the gap at w* +/- 1 cm ==")
    fits = {"narrowest": narrowest, "c*(w* + 0.5 cm)": curve[near[0]]}
    verify(problem, search, w_star, fits, args.search)

    print("\n== the start formation at every heading ==")
    check_start(problem, search)

    date = subprocess.run(["date", "-u"], capture_output=True, text=True).stdout.strip()
    print(f"\n{date}; {time.perf_counter() - started:.0f} s")


if __name__ == "__main__":
    main()
