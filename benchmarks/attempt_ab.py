"""bitrrt's time per expansion attempt, this checkout against another, in lockstep.

    .venv/bin/python benchmarks/attempt_ab.py BASE_CHECKOUT [--scene puzzle] [--chunk 10]
        [--rounds 20]

Why: on a shared machine the same code's time per attempt drifts by a third within an hour,
so two runs one after the other compare the hours, not the code. Here one process per
checkout (each with its own numba cache, warmed before timing) plans the same chunk of
seeds in turn, the order swapped every round; the figure is the median of the rounds'
time ratios (this checkout over the base), with their quartiles. Both must make the same
attempts per chunk, or the comparison stops: a change meant to be faster only must not
change the trees. Seeds are planned through a task's defaults (:func:`~missions.task.
resolve.resolve_task`, the planning checker and bitrrt's configuration).
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parents[1]


def serve() -> None:
    """The worker: reads "scene first count" lines, prints "seconds attempts" for each."""
    from flycrane.planning.algorithms.bitrrt import BiTRRT
    from flycrane.planning.planners import PlannerOptions
    from flycrane.planning.result import TerminationCondition
    from missions.task.resolve import resolve_task
    from missions.task.spec import TaskSpec

    config = PlannerOptions().bitrrt_config()
    tasks = {}
    for line in sys.stdin:
        scene, first, count = line.split()
        if scene not in tasks:
            tasks[scene] = task = resolve_task(TaskSpec(scene=scene))
            planner = BiTRRT(task.problem.space, task.checkers.planning, config)
            planner.solve(task.start, task.goal, TerminationCondition(600.0), seed=99)  # compile
        task = tasks[scene]
        began, attempts = time.perf_counter(), 0
        for seed in range(int(first), int(first) + int(count)):
            planner = BiTRRT(task.problem.space, task.checkers.planning, config)
            result = planner.solve(task.start, task.goal, TerminationCondition(60.0), seed=seed)
            attempts += result.statistics.expansion_attempts
        print(time.perf_counter() - began, attempts, flush=True)


def worker(checkout: Path) -> subprocess.Popen[str]:
    env = dict(os.environ, PYTHONPATH=str(checkout))
    cache = Path(tempfile.gettempdir()) / "flycrane-ab" / str(checkout).strip("/").replace("/", "-")
    env["NUMBA_CACHE_DIR"] = str(cache)  # each checkout's kernels compiled and kept apart
    return subprocess.Popen(
        [sys.executable, str(Path(__file__).resolve()), "--serve"],
        cwd=checkout, env=env, stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True,
    )  # fmt: skip


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("base", nargs="?", type=Path, help="the other checkout's root")
    parser.add_argument("--scene", default="puzzle")
    parser.add_argument("--chunk", type=int, default=10, help="seeds per round")
    parser.add_argument("--rounds", type=int, default=20)
    parser.add_argument("--serve", action="store_true", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.serve:
        return serve()
    if args.base is None or not (args.base / "flycrane").is_dir():
        parser.error("base: the root of another checkout of this project is needed")
    base, new = worker(args.base.resolve()), worker(HERE)
    ratios, attempts, spent = [], 0, {base: 0.0, new: 0.0}
    try:
        for round_ in range(args.rounds):
            line = f"{args.scene} {round_ * args.chunk} {args.chunk}\n"
            figures = {}
            for process in (base, new) if round_ % 2 == 0 else (new, base):
                assert process.stdin is not None and process.stdout is not None
                process.stdin.write(line)
                process.stdin.flush()
                seconds, count = process.stdout.readline().split()
                figures[process] = (float(seconds), int(count))
            if figures[base][1] != figures[new][1]:
                sys.exit(f"round {round_}: {figures[base][1]} attempts against {figures[new][1]}")
            ratios.append(figures[new][0] / figures[base][0])
            attempts += figures[base][1]
            for process in (base, new):
                spent[process] += figures[process][0]
    finally:
        for process in (base, new):
            if process.stdin is not None:
                process.stdin.close()
            process.wait()
    low, _, high = statistics.quantiles(ratios, n=4)
    print(
        f"{args.scene}: this checkout over the base {statistics.median(ratios):.3f} "
        f"(quartiles {low:.3f}-{high:.3f}) over {args.rounds} rounds of {args.chunk} seeds; "
        f"per attempt {spent[base] / attempts * 1e6:.1f} us (base), "
        f"{spent[new] / attempts * 1e6:.1f} us (this), {attempts} attempts each"
    )


if __name__ == "__main__":
    main()
