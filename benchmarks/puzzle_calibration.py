"""Puzzle calibration runs: plan variants of the Puzzle passage over seeds.

    python benchmarks/puzzle_calibration.py --runs 3 --budget 60 \\
        --variant '{"slab": 0.1, "hole": [1.2, 0.5], "spacing": 0.8}' \\
        --bounds '{"position_low": [-3.5, -1.5, 3.5], "position_high": [1.5, 1.5, 7.5]}'

A variant changes the slab thickness, the hole (x, y), the spacing of the two bars (the
upper bar stays 1.1 m below P; a wider spacing lengthens the rod downwards), the bars'
lengths and the start height (design.md section 7 names these levers), the alphas of the
start and goal hover (``hover_alpha``), and optionally the sampling bounds and the planner
step; the goal stays 0.4 m above the slab's top. For each planner it prints the solved runs
and their times. BENCHMARKS.md ("Puzzle: calibration and Table I") records what was run.
"""

from __future__ import annotations

import argparse
import json
import multiprocessing
import tomllib
from concurrent.futures import ProcessPoolExecutor

from bench_input import at_least_one

from flycrane.planning.planners import PlannerOptions, plan
from flycrane.planning.problem import PlanningProblem
from flycrane.world.scene import SCENES_DIR, SceneSpec, scene_from_dict

SLAB_BOTTOM, SLAB_HALF_WIDTH = 4.0, 6.0


def puzzle_variant(
    slab: float = 0.2,
    hole: tuple[float, float] = (1.1, 0.5),
    spacing: float = 0.5,
    long_bar: float = 1.3,
    short_bar: float = 0.8,
    start_z: float | None = None,
    hover_alpha: float | None = None,
    bounds: dict | None = None,
) -> SceneSpec:
    """The shipped Puzzle (its start, goal alphas and bounds) with another passage; the
    defaults are design.md's first geometry, whose upper bar needs sigma's full range."""
    data = tomllib.loads((SCENES_DIR / "puzzle.toml").read_text(encoding="utf-8"))
    a, b = hole
    z = SLAB_BOTTOM + slab / 2
    side = SLAB_HALF_WIDTH - a / 2
    end = SLAB_HALF_WIDTH - b / 2
    data["obstacles"] = [
        {
            "kind": "box",
            "name": "slab west",
            "center": [-(SLAB_HALF_WIDTH + a / 2) / 2, 0, z],
            "size": [side, 2 * SLAB_HALF_WIDTH, slab],
        },
        {
            "kind": "box",
            "name": "slab east",
            "center": [(SLAB_HALF_WIDTH + a / 2) / 2, 0, z],
            "size": [side, 2 * SLAB_HALF_WIDTH, slab],
        },
        {
            "kind": "box",
            "name": "slab north",
            "center": [0, (SLAB_HALF_WIDTH + b / 2) / 2, z],
            "size": [a, end, slab],
        },
        {
            "kind": "box",
            "name": "slab south",
            "center": [0, -(SLAB_HALF_WIDTH + b / 2) / 2, z],
            "size": [a, end, slab],
        },
    ]
    # The upper bar stays where it is below P; a wider spacing lengthens the rod downwards.
    rod, lower, upper = data["payload"]["shapes"]
    lower_z = upper["center"][2] - spacing
    rod["center"], rod["size"] = [0.0, 0.0, lower_z / 2], [0.06, 0.06, -lower_z]
    lower["center"], lower["size"] = [0.0, 0.0, lower_z], [long_bar, 0.08, 0.08]
    upper["size"] = [0.08, short_bar, 0.08]
    if start_z is not None:
        data["start"][2] = start_z
    data["goal"] = [0.0, 0.0, SLAB_BOTTOM + slab + 0.4, 0.0, 0.0, 0.0, *data["goal"][6:]]
    if hover_alpha is not None:
        data["start"][6:] = data["goal"][6:] = [hover_alpha] * 3
    if bounds:
        data["bounds"].update(bounds)
    return scene_from_dict(data, "puzzle variant")


def run(variant: dict, bounds: dict | None, algorithm: str, seed: int, budget: float, step):
    problem = PlanningProblem.from_scene(puzzle_variant(**variant, bounds=bounds))
    options = PlannerOptions(algorithm=algorithm, seed=seed, time_budget=budget, step=step)
    outcome = plan(problem.space, problem.validity, problem.start, problem.goal, options)
    return algorithm, seed, outcome.result.status.value, outcome.result.statistics.time


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--variant", type=json.loads, default={})
    parser.add_argument("--bounds", type=json.loads, default=None)
    parser.add_argument("--planners", nargs="+", default=["trrt", "rrt"])
    parser.add_argument("--runs", type=at_least_one, default=3)
    parser.add_argument("--budget", type=float, default=60.0)
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--step", type=float, default=None, help="planner step (None: default)")
    parser.add_argument("--first-seed", type=int, default=0)
    args = parser.parse_args()
    seeds = range(args.first_seed, args.first_seed + args.runs)
    jobs = [(args.variant, args.bounds, p, s, args.budget, args.step)
            for p in args.planners for s in seeds]  # fmt: skip
    context = multiprocessing.get_context("spawn")
    with ProcessPoolExecutor(args.workers, mp_context=context) as pool:
        results = list(pool.map(run, *zip(*jobs, strict=True)))
    print(f"variant {args.variant} bounds {args.bounds} step {args.step}")
    for planner in args.planners:
        mine = [r for r in results if r[0] == planner]
        solved = [r for r in mine if r[2] == "exact_solution"]
        times = ", ".join(f"{r[3]:.1f}" for r in mine)
        print(f"  {planner}: {len(solved)}/{len(mine)} solved; times [s]: {times}")


if __name__ == "__main__":
    main()
