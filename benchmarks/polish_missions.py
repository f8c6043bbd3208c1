"""Missions from polished and unpolished paths: does the formation polish cost mission
generation, and what does it buy in the least thrust margin?

    python benchmarks/polish_missions.py --scenes rescue puzzle --runs 30

Each (scene, seed) is run as the service runs a task (:func:`missions.task.pipeline.run_task`,
default mission options, so the planning clearance of the default position-error model)
with ``planner.polish`` off and on; the table gives per scene and variant the tasks whose
missions were generated ("done"), the others' reasons, and the median and worst least
margins of the planned paths (:func:`flycrane.analysis.profiles.least_margins`). BENCHMARKS.md
("Formation polish") records the runs.
"""

from __future__ import annotations

import argparse
import tempfile
from concurrent.futures import ProcessPoolExecutor

import numpy as np
from bench_input import at_least_one

from flycrane.analysis.profiles import least_margins, path_profile
from flycrane.planning.planners import PlannerOptions
from missions.task.directory import TaskDirectory, TaskDirectoryError
from missions.task.pipeline import run_task
from missions.task.resolve import resolve_task
from missions.task.spec import TaskSpec


def run(scene: str, polish: bool, seed: int, budget: float) -> tuple[str, str, tuple | None]:
    """(status, reason, (slack, thrust, headroom) of the planned path or None)."""
    task = TaskSpec(
        scene=scene, planner=PlannerOptions(seed=seed, time_budget=budget, polish=polish)
    )
    resolved = resolve_task(task)
    with tempfile.TemporaryDirectory() as out:
        outcome = run_task(task, out, resolved=resolved)
        try:  # a path the missions could not be built from was still planned
            path = TaskDirectory(out).planned_path()
        except TaskDirectoryError:
            return outcome.status, outcome.reason, None
    problem = resolved.problem
    margins = least_margins(path_profile(problem.system, problem.space, path), problem.system)
    return outcome.status, outcome.reason, (margins.slack, margins.thrust, margins.headroom)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenes", nargs="+", default=["rescue", "puzzle"])
    parser.add_argument("--runs", type=at_least_one, default=30)
    parser.add_argument("--budget", type=float, default=60.0)
    parser.add_argument("--workers", type=int, default=2)
    args = parser.parse_args()
    jobs = [
        (scene, polish, seed, args.budget)
        for scene in args.scenes
        for polish in (False, True)
        for seed in range(args.runs)
    ]
    with ProcessPoolExecutor(args.workers) as pool:
        results = list(pool.map(run, *zip(*jobs, strict=True)))
    print(f"{'scene':<10} {'polish':<7} done   slack [worst]  thrust [worst]  headroom [worst]")
    for scene in args.scenes:
        for polish in (False, True):
            mine = [(job[2], r) for job, r in zip(jobs, results, strict=True)
                    if job[:2] == (scene, polish)]  # fmt: skip
            done = sum(r[0] == "done" for _, r in mine)
            rows = np.array([r[2] for _, r in mine if r[2] is not None])
            margins = "  ".join(
                f"{np.median(rows[:, k]):5.2f} [{rows[:, k].min():5.2f}]" for k in (0, 1, 2)
            )
            print(f"{scene:<10} {polish!s:<7} {done:2d}/{len(mine):<3d} {margins}")
            for seed, (status, reason, _) in mine:
                if status != "done":
                    print(f"    seed {seed}: {status}: {reason}")


if __name__ == "__main__":
    main()
