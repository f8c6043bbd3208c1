"""The gap's gradient (the robust margin's inner loop): from fcl's nearest points against
central differences, in one process.

    .venv/bin/python benchmarks/gap_gradients.py [--scenes rescue puzzle corridor] [--samples 400] \
        [--refine 10]

Per scene: configurations near obstacles (the planner's paths of seeds 0-9 at 5 cm, those
within 25 cm of an obstacle, as :class:`~flycrane.planning.robust_clearance.
RobustClearance` measures them), their gaps and gradients by
:meth:`~flycrane.world.collision.CollisionChecker.gap_gradients` as it is and with the
nearest points never trusted (central differences, as before), the two run in turn five
times. Prints the median time per configuration of each, their ratio and the largest
difference of the gradients. With ``--refine N``: the refinement of seeds 0 to N - 1
(``improve_time`` 5 s, keeping the ``rtk`` model's robust margin, as
``benchmarks/anytime_improvement.py``) both ways, seed by seed in turn: its time and avgC.
"""

from __future__ import annotations

import argparse
import statistics
import time

import numpy as np

from flycrane.planning.planners import PlannerOptions, plan
from flycrane.planning.problem import PlanningProblem
from flycrane.planning.robust_clearance import RobustClearance
from flycrane.world import collision
from missions.position_error import PRESETS

WAYS = {"nearest points": collision.NEAREST_TOLERANCE, "central differences": -1.0}


def near_configurations(problem: PlanningProblem, samples: int) -> np.ndarray:
    """Up to ``samples`` configurations of the planner's paths within 25 cm of an obstacle."""
    checker = problem.validity.with_clearance(0.0)
    reach = checker.with_clearance(0.25)
    found = []
    for seed in range(10):
        outcome = plan(
            problem.space, problem.validity, problem.start, problem.goal, PlannerOptions(seed=seed)
        )
        q = problem.space.discretize_path(outcome.path, 0.05)
        found.append(q[~reach.is_safe(q)])
    return np.concatenate(found)[:samples]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenes", nargs="+", default=["rescue", "puzzle", "corridor"])
    parser.add_argument("--samples", type=int, default=400)
    parser.add_argument("--refine", type=int, default=0, help="seeds refined both ways")
    args = parser.parse_args()
    for scene in args.scenes:
        problem = PlanningProblem.named(scene)
        checker = problem.validity.with_clearance(0.0).collision
        q = near_configurations(problem, args.samples)
        times: dict[str, list[float]] = {name: [] for name in WAYS}
        results = {}
        for _ in range(5):
            for name, tolerance in WAYS.items():
                collision.NEAREST_TOLERANCE = tolerance
                clock = time.perf_counter()
                results[name] = checker.gap_gradients(q)
                times[name].append((time.perf_counter() - clock) / len(q))
        collision.NEAREST_TOLERANCE = WAYS["nearest points"]
        mine, before = (statistics.median(times[k]) * 1e6 for k in times)
        difference = np.abs(results["nearest points"][1] - results["central differences"][1])
        print(
            f"{scene}: {len(q)} configurations; per configuration {mine:.0f} us from nearest "
            f"points, {before:.0f} us by central differences ({before / mine:.2f}x); gradients "
            f"differ by {difference.max():.2g} at most, {np.median(difference.max(axis=1)):.2g} "
            "at the median"
        )

        if args.refine:
            refinements(problem, args.refine)


def refinements(problem: PlanningProblem, seeds: int) -> None:
    """The refinement's time and avgC, both ways, seed by seed in turn."""
    model = PRESETS["rtk"]
    robust = RobustClearance(
        problem.validity.with_clearance(0.0),
        (model.common_horizontal, model.common_vertical),
        model.own,
    )
    rows: dict[str, list[tuple[float, float]]] = {name: [] for name in WAYS}
    for seed in range(seeds):
        for name, tolerance in WAYS.items():
            collision.NEAREST_TOLERANCE = tolerance
            options = PlannerOptions(seed=seed, improve_time=5.0)
            outcome = plan(
                problem.space, problem.validity, problem.start, problem.goal, options, robust=robust
            )
            assert outcome.metrics is not None
            rows[name].append((outcome.smoothing_time, outcome.metrics.avg_cost))
    collision.NEAREST_TOLERANCE = WAYS["nearest points"]
    mine, before = (np.array(rows[name]) for name in WAYS)
    print(
        f"  refined, {seeds} seeds: smoothing, polish and refinement {np.median(mine[:, 0]):.2f} s "
        f"at the median from nearest points, {np.median(before[:, 0]):.2f} s by central "
        f"differences (per seed, time ratio median {np.median(before[:, 0] / mine[:, 0]):.2f}); "
        f"avgC median {np.median(mine[:, 1]):.3g} and {np.median(before[:, 1]):.3g}, the same "
        f"in {np.sum(np.isclose(mine[:, 1], before[:, 1], rtol=1e-9))} seeds"
    )


if __name__ == "__main__":
    main()
