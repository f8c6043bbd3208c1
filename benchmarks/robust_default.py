"""Tasks planned keeping one clearance against tasks planned until the drones' errors cannot
close the gap (``mission.robust_clearance`` off and on), seed by seed in one process.

    .venv/bin/python benchmarks/robust_default.py --scenes rescue puzzle --seeds 0-19 \
        [--position-error rtk]

For each scene and seed the whole task runs twice, alternating (``run_task``: planning,
the missions and their checks, every file written): once with ``robust_clearance`` off,
once on. Per run it records the status, the wall time, the clearance the path kept, its
robust margin (measured on the fixed-clearance path too, which the task does not do) and
robust statics margin, the plans tried and the mission's duration; it prints a table per
scene with the median time ratio (on / off) and its 95 % bootstrap interval.
"""

from __future__ import annotations

import argparse
import json
import statistics
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np
from scipy.stats import bootstrap
from sitl_seeds import seeds  # the seeds' syntax, shared

from missions.options import MissionOptions
from missions.task.directory import PATH_FILE, TaskDirectory
from missions.task.pipeline import run_task
from missions.task.resolve import resolve_task
from missions.task.spec import TaskSpec


def run(scene: str, seed: int, position_error: str, robust: bool, out: Path) -> dict:
    task = TaskSpec(
        scene=scene,
        planner={"seed": seed},
        mission=MissionOptions(position_error=position_error, robust_clearance=robust),
    )
    start = time.perf_counter()
    outcome = run_task(task, out)
    elapsed = time.perf_counter() - start
    row = {"status": outcome.status, "time": elapsed, "plans": len(outcome.attempts) + 1}
    if outcome.status != "done" or outcome.mission is None:
        return {**row, "reason": outcome.reason}
    mission = outcome.mission
    margin = mission.robust_margin
    if margin is None:  # not measured by the task: measure the path it built
        path = np.array(json.loads(TaskDirectory(out).read_text(PATH_FILE))["configurations"])
        resolved = resolve_task(task)
        margin = resolved.robust.margin(path, resolved.problem.space)
    return {
        **row,
        "clearance": mission.obstacle_clearance,
        "robust_margin": float(margin),
        "statics_margin": mission.robust_statics_margin,
        "duration": mission.duration,
    }


def interval(ratios: list[float], rng: np.random.Generator) -> str:
    """95 % percentile bootstrap interval of the median of ``ratios`` (scipy.stats), or
    n/a with fewer than two (one seed: nothing to resample)."""
    if len(ratios) < 2:
        return "n/a"
    found = bootstrap((ratios,), np.median, method="percentile", n_resamples=2000, rng=rng)
    return f"{found.confidence_interval.low:.2f}, {found.confidence_interval.high:.2f}"


def figure(values: list[float], spec: str, summary: Callable = statistics.median) -> str:
    """``summary`` of ``values`` formatted by ``spec``, or n/a when there are none (no run
    of the arm was done)."""
    return format(summary(values), spec) if values else "n/a"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenes", nargs="+", default=["rescue", "puzzle"])
    parser.add_argument("--seeds", type=seeds, default=seeds("0-19"), help="e.g. 0-19")
    parser.add_argument("--position-error", default="rtk")
    parser.add_argument("--json", type=Path, help="write every run's figures here")
    args = parser.parse_args(argv)
    rng = np.random.default_rng(0)
    runs: dict[str, dict[str, list[dict]]] = {}
    with tempfile.TemporaryDirectory() as scratch:
        for scene in args.scenes:
            runs[scene] = {"off": [], "on": []}
            for seed in args.seeds:
                for arm in ("off", "on"):
                    out = Path(scratch) / f"{scene}-{seed}-{arm}"
                    row = run(scene, seed, args.position_error, arm == "on", out)
                    runs[scene][arm].append({"seed": seed, **row})
                    print(scene, seed, arm, json.dumps(row), flush=True)
    if args.json:
        args.json.write_text(json.dumps(runs, indent=1))
    print()
    print("| scene | robust_clearance | done | plans, median (max) | time [s], median | "
          "clearance [cm], median (max) | robust margin [cm], min / median | below zero | "
          "robust statics [N], min | duration [s], median |")  # fmt: skip
    print("| --- | --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |")
    for scene, arms in runs.items():
        for arm, rows in arms.items():
            done = [r for r in rows if r["status"] == "done"]
            cm = [100 * r["clearance"] for r in done]
            rm = [100 * r["robust_margin"] for r in done]
            sm = [r["statics_margin"] for r in done if r["statics_margin"] is not None]
            duration = [r["duration"] for r in done]
            print(
                f"| {scene} | {arm} | {len(done)}/{len(rows)} | "
                f"{statistics.median(r['plans'] for r in rows):g} "
                f"({max(r['plans'] for r in rows)}) | "
                f"{statistics.median(r['time'] for r in rows):.2f} | "
                f"{figure(cm, '.1f')} ({figure(cm, '.1f', max)}) | "
                f"{figure(rm, '.1f', min)} / {figure(rm, '.1f')} | {sum(m < 0 for m in rm)} | "
                f"{figure(sm, '.2f', min)} | {figure(duration, '.1f')} |"
            )
    print()
    for scene, arms in runs.items():
        ratios = [b["time"] / a["time"] for a, b in zip(arms["off"], arms["on"], strict=True)]
        print(f"{scene}: task time on / off, median {statistics.median(ratios):.2f} "
              f"[{interval(ratios, rng)}], max {max(ratios):.2f}")  # fmt: skip
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
