"""Path quality of bitrrt variants against T-RRT: Table I's costs and Fig. 6's least margins.

    python benchmarks/planner_quality.py --scenes rescue puzzle --runs 100 \\
        --variant default '{}' --variant repair-0.2 '{"repair_share": 0.2}' \\
        --variant unpolished '{"polish": false}' --trrt

Each variant is a name and the fields it changes, of PlannerOptions (e.g. ``polish``) or
else of BiTRRTConfig; ``--trrt`` adds the paper's T-RRT. Every (scene, variant, seed) is
planned, smoothed and measured as ``flycrane bench`` does
(:func:`flycrane.planning.planners.plan`), in a pool of worker processes; the table
gives per scene and variant the solved runs, the mean average and maximum cost, and the
least margins along the paths (:func:`flycrane.analysis.profiles.least_margins`: median and worst
run). BENCHMARKS.md ("Planner v2", "Against T-RRT") records the runs behind bitrrt's
``repair_share``.
"""

from __future__ import annotations

import argparse
import json
from concurrent.futures import ProcessPoolExecutor
from dataclasses import replace

import numpy as np
from bench_input import at_least_one

from flycrane.analysis.profiles import least_margins, path_profile
from flycrane.planning.algorithms.bitrrt import BiTRRT
from flycrane.planning.planners import PlannerOptions, plan
from flycrane.planning.problem import PlanningProblem

TRRT = "trrt"


def run(scene: str, variant: str, fields: str, seed: int, budget: float) -> tuple | None:
    """(avgC, maxC, least slack, thrust and headroom margins) of one smoothed path, or None
    if not solved."""
    problem = PlanningProblem.named(scene)
    algorithm = "trrt" if variant == TRRT else "bitrrt"
    changes = json.loads(fields or "{}")
    option_changes = {k: changes.pop(k) for k in list(changes) if k in PlannerOptions.model_fields}
    options = PlannerOptions(algorithm=algorithm, seed=seed, time_budget=budget, **option_changes)
    planner = None
    if algorithm == "bitrrt":
        config = replace(options.bitrrt_config(), **changes)
        planner = BiTRRT(problem.space, problem.validity, config)
    outcome = plan(
        problem.space, problem.validity, problem.start, problem.goal, options, planner=planner
    )
    if outcome.metrics is None:
        return None
    margins = least_margins(
        path_profile(problem.system, problem.space, outcome.path), problem.system
    )
    return (
        outcome.metrics.avg_cost,
        outcome.metrics.max_cost,
        margins.slack,
        margins.thrust,
        margins.headroom,
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenes", nargs="+", required=True)
    parser.add_argument("--runs", type=at_least_one, default=100)
    parser.add_argument("--first-seed", type=int, default=0)
    parser.add_argument("--budget", type=float, default=60.0)
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--variant", nargs=2, action="append", default=[], metavar=("NAME", "JSON"))
    parser.add_argument("--trrt", action="store_true", help="also the paper's T-RRT")
    args = parser.parse_args()
    variants = [*args.variant, *([(TRRT, "")] if args.trrt else [])]
    jobs = [
        (scene, name, fields, seed, args.budget)
        for scene in args.scenes
        for name, fields in variants
        for seed in range(args.first_seed, args.first_seed + args.runs)
    ]
    with ProcessPoolExecutor(args.workers) as pool:
        results = list(pool.map(run, *zip(*jobs, strict=True)))
    print(f"{'scene':<14} {'variant':<14} solved  avgC mean  maxC mean  slack [worst]  "
          "thrust [worst]  headroom [worst]")  # fmt: skip
    table = {
        (scene, name): np.array(
            [r for job, r in zip(jobs, results, strict=True) if job[:2] == (scene, name) and r]
        )
        for scene in args.scenes
        for name, _ in variants
    }
    for scene in args.scenes:
        for name, _ in variants:
            rows = table[scene, name]
            if not len(rows):
                print(f"{scene:<14} {name:<14} 0/{args.runs}")
                continue
            margins = "  ".join(
                f"{np.median(rows[:, k]):5.2f} [{rows[:, k].min():5.2f}]" for k in (2, 3, 4)
            )
            print(
                f"{scene:<14} {name:<14} {len(rows):3d}/{args.runs:<3d} {rows[:, 0].mean():9.3g} "
                f"{rows[:, 1].mean():9.4g}  {margins}",
                flush=True,
            )
    if args.trrt:
        print("\nAgainst T-RRT: 95 % bootstrap intervals of the difference (variant - trrt) of "
              "mean avgC and of the median least margins")  # fmt: skip
        for scene in args.scenes:
            for name, _ in args.variant:
                print(f"{scene:<14} {name:<14} {against(table[scene, name], table[scene, TRRT])}")


#: The statistics compared with T-RRT's: column of run()'s tuple, name, statistic.
COMPARED = ((0, "avgC", np.mean), (2, "slack", np.median), (3, "thrust", np.median),
            (4, "headroom", np.median))  # fmt: skip


def against(rows: np.ndarray, reference: np.ndarray, draws: int = 2000) -> str:
    """Bootstrap intervals (percentile, ``draws`` resamples of each side's runs) of the
    difference of avgC's mean and of the least margins' medians, rows minus reference."""
    rng = np.random.default_rng(0)
    if not (len(rows) and len(reference)):
        return "-"
    parts = []
    for k, label, stat in COMPARED:
        mine = rows[rng.integers(0, len(rows), (draws, len(rows))), k]
        theirs = reference[rng.integers(0, len(reference), (draws, len(reference))), k]
        difference = stat(mine, axis=1) - stat(theirs, axis=1)
        low, high = np.percentile(difference, [2.5, 97.5])
        point = stat(rows[:, k]) - stat(reference[:, k])
        parts.append(f"{label} {point:+.3g} [{low:+.3g}, {high:+.3g}]")
    return "  ".join(parts)


if __name__ == "__main__":
    main()
