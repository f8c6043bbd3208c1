"""Fly the benchmark tasks on three ArduCopter SITL instances and print the flight report's
figures (issue 11; design.md section 9 has what the first exports did).

Each task is planned once (``flycrane.pipeline.run_task`` with the given position-error
model), then flown ``--runs`` times by ``flycrane fly-sitl`` (its own private network
namespace, simulators killed by PID). One row per flight: duration ratio, release and
progress spread, each source's worst per-drone error p95 and inter-drone error p95, the
true load's least clearance and margins, and the verdict.

    .venv/bin/python benchmarks/sitl_flights.py [--scenes rescue puzzle] [--runs 3]
        [--speedup 10] [--position-error sitl] [--out sitl-bench]
"""

from __future__ import annotations

import argparse
import json
import platform
import subprocess
import sys
from datetime import UTC, datetime
from pathlib import Path

from bench_input import at_least_one

from flycrane.planning.planners import PlannerOptions
from missions.options import MissionOptions
from missions.task.pipeline import run_task
from missions.task.spec import TaskSpec

#: The seeds the SITL tests plan with (tests/missions/sitl/test_flights.py).
SEEDS = {"rescue": 0, "puzzle": 2}


def plan(scene: str, position_error: str, out: Path) -> Path:
    task = TaskSpec(
        scene=scene,
        planner=PlannerOptions(seed=SEEDS.get(scene, 0), time_budget=120),
        mission=MissionOptions(position_error=position_error),
    )
    outcome = run_task(task, out)
    if outcome.status != "done":
        raise SystemExit(f"{scene}: no mission ({outcome.status}: {outcome.reason})")
    return out


def fly(task_dir: Path, out: Path, speedup: float) -> dict:
    command = [sys.executable, "-m", "flycrane.cli", "fly-sitl", str(task_dir), "--out",
               str(out), "--speedup", str(speedup)]  # fmt: skip
    done = subprocess.run(command, capture_output=True, text=True, timeout=1800)
    if done.returncode not in (0, 1):
        raise SystemExit(f"fly-sitl failed:\n{done.stderr[-3000:]}")
    return json.loads((out / "report.json").read_text())


def row(scene: str, run: int, report: dict) -> str:
    timing, estimated, true = report["timing"], report["estimated"], report["true"] or {}

    def both(name: str) -> str:
        """The estimated and the true figure (the worst drone's where there are three)."""
        values = [source.get(name, float("nan")) for source in (estimated, true)]
        return " / ".join(f"{max(v) if isinstance(v, list) else v:.3f}" for v in values)

    cells = [
        scene,
        str(run),
        f"{report['planned_duration']:.1f}",
        f"{timing['flown_duration'] / report['planned_duration']:.3f}",
        f"{report['release_spread'] * 1000:.1f}",
        f"{timing['progress_spread_p95']:.3f}",
        f"{report['start_offset_tolerance']:.3f}",
        both("error_in_time_p95"),
        both("error_off_path_p95"),
        both("inter_drone_error_p95"),
        f"{true.get('least_clearance', float('nan')):.3f}",
        f"{true.get('least_slack_margin', float('nan')):.2f}",
        f"{true.get('least_thrust_margin', float('nan')):.2f}",
        "safe" if report["verdict"]["safe"] else "UNSAFE",
    ]
    return "| " + " | ".join(cells) + " |"


HEADER = (
    "| scene | run | planned [s] | flown/planned | release spread [ms] | progress spread p95 [s] "
    "| tolerance [s] | error in time p95 est/true [m] | off path p95 est/true [m] "
    "| inter-drone p95 est/true [m] | true clearance [m] | true slack margin [N] "
    "| true thrust margin [N] | verdict |"
)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--scenes", nargs="+", default=["rescue", "puzzle"])
    parser.add_argument("--runs", type=at_least_one, default=1)
    parser.add_argument("--speedup", type=float, default=10.0)
    parser.add_argument("--position-error", default="sitl")
    parser.add_argument("--out", default="sitl-bench")
    args = parser.parse_args()
    out = Path(args.out)
    machine = platform.processor() or platform.machine()
    print(f"# {datetime.now(UTC):%Y-%m-%d %H:%M} UTC, {machine}, speed-up {args.speedup}, "
          f"position error {args.position_error}")  # fmt: skip
    print(HEADER)
    print("|" + " --- |" * (HEADER.count("|") - 1))
    for scene in args.scenes:
        task_dir = plan(scene, args.position_error, out / scene / "task")
        for run in range(1, args.runs + 1):
            report = fly(task_dir, out / scene / f"flight{run}", args.speedup)
            print(row(scene, run, report), flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
