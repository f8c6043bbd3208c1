"""Measure variants of the bidirectional T-RRT on scenes over seeds, in one process.

    python benchmarks/planner_variants.py --scenes corridor puzzle_broad --runs 10 \\
        --budget 60 --variant default '{}' --variant no-repair '{"repair_alphas": false}'

Each variant is a name and the BiTRRTConfig fields it changes. Every (scene, variant, seed)
runs the planner alone (no smoothing) after a warm-up run that compiles the kernels; the
table gives solved runs, median and mean time (a timeout counts its budget), median
attempts and the median time per attempt. BENCHMARKS.md ("Planner v2") records the runs
behind each choice of :mod:`flycrane.planning.algorithms.bitrrt`.
"""

from __future__ import annotations

import argparse
import json

import numpy as np
from bench_input import at_least_one

from flycrane.planning.algorithms.bitrrt import BiTRRT, BiTRRTConfig
from flycrane.planning.problem import PlanningProblem
from flycrane.planning.result import TerminationCondition


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenes", nargs="+", required=True)
    parser.add_argument("--runs", type=at_least_one, default=10)
    parser.add_argument("--first-seed", type=int, default=0)
    parser.add_argument("--budget", type=float, default=60.0)
    parser.add_argument(
        "--variant", nargs=2, action="append", metavar=("NAME", "JSON"), required=True
    )
    parser.add_argument("--verbose", action="store_true", help="one line per run")
    args = parser.parse_args()
    seeds = range(args.first_seed, args.first_seed + args.runs)
    for scene in args.scenes:
        problem = PlanningProblem.named(scene)
        for name, fields in args.variant:
            planner = BiTRRT(problem.space, problem.validity, BiTRRTConfig(**json.loads(fields)))
            planner.solve(problem.start, problem.goal, TerminationCondition(1.0), seed=10**6)
            times, attempts, per_attempt, solved = [], [], [], 0
            for seed in seeds:
                result = planner.solve(
                    problem.start, problem.goal, TerminationCondition(args.budget), seed=seed
                )
                stats = result.statistics
                solved += result.status.solved
                times.append(stats.time)
                attempts.append(stats.expansion_attempts)
                per_attempt.append(stats.time / max(stats.expansion_attempts, 1))
                if args.verbose:
                    print(f"  {scene} {name} seed {seed}: {result.status.value} "
                          f"{stats.time:.2f} s, X {stats.expansion_attempts}, N {stats.nodes}",
                          flush=True)  # fmt: skip
            print(
                f"{scene:14s} {name:18s} {solved:3d}/{len(times):<3d} median "
                f"{np.median(times):6.2f} s  mean {np.mean(times):6.2f} s  "
                f"max {np.max(times):6.2f} s  "
                f"X {np.median(attempts):8.0f}  {1e6 * np.median(per_attempt):5.0f} us/X",
                flush=True,
            )


if __name__ == "__main__":
    main()
