"""``flycrane plan``: a task file (or the Rescue defaults) to missions, logs and plots."""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

from flycrane.errors import FieldProblem, InputError
from flycrane.planning.result import PlanningProgress
from flycrane.user_files import output_directory


def _progress(stage: str, report: PlanningProgress | None) -> None:
    if report is None:
        print(f"  {stage} ...", file=sys.stderr, flush=True)
    else:
        print(
            f"  planning: {report.elapsed:5.1f} s, {report.nodes} nodes, "
            f"{report.expansion_attempts} attempts, {report.distance_to_goal:.2f} from the goal",
            file=sys.stderr,
            flush=True,
        )


def _cmd_plan(args: argparse.Namespace) -> int:
    from missions.task.directory import (
        MCAP_FILE,
        PROFILE_FILE,
        SUMMARY_FILE,
        TASK_FILE,
        mission_file,
    )
    from missions.task.documents import raised_clearance
    from missions.task.pipeline import run_task
    from missions.task.resolve import resolve_task
    from missions.task.spec import TaskSpec, load_task

    if args.task:
        task, base_dir = load_task(args.task)
    else:
        task, base_dir = TaskSpec(name="rescue (defaults)"), None
    clock = time.perf_counter()
    resolved = resolve_task(task, base_dir)
    out = output_directory(args.out)
    if args.task and (out / TASK_FILE).resolve() == Path(args.task).resolve():
        raise InputError([FieldProblem("--out", (
            f"{out} holds the task being planned ({args.task}), which the run would replace "
            "with its own task.json: plan into another directory"))])  # fmt: skip
    print(
        f"planning {task.name or 'task'}: scene {resolved.problem.scene.name}, "
        f"planner {resolved.algorithm}, seed {task.planner.seed}",
        file=sys.stderr,
    )
    outcome = run_task(task, out, progress=_progress, base_dir=base_dir, resolved=resolved)
    print(f"status: {outcome.status}" + (f" ({outcome.reason})" if outcome.reason else ""))
    for attempt in outcome.attempts:
        seed, reason = attempt["seed"], attempt["reason"]
        if raised_clearance(attempt):
            print(f"  seed {seed}: {reason}")
        else:
            print(f"  seed {seed}: its missions failed their check ({reason})")
    stats = outcome.planner_statistics
    print(
        f"planner: {outcome.planner_status} in {stats.get('time', 0):.2f} s, "
        f"{stats.get('nodes', 0)} nodes, {stats.get('expansion_attempts', 0)} attempts"
    )
    if outcome.metrics:
        m = outcome.metrics
        print(
            f"path: avgC {m.avg_cost:.3g}, maxC {m.max_cost:.3g}, "
            f"MW {m.mechanical_work:.3g}, IC {m.cost_integral:.3g}"
        )
    if outcome.mission:
        mission, tolerance = outcome.mission, outcome.mission.timing_tolerance
        print(
            f"mission: {mission.waypoints} waypoints, {mission.duration:.1f} s; "
            f"tolerates {tolerance.start_offset:.2f} s start offset "
            f"({tolerance.start_offset_case}) and {100 * tolerance.speed_mismatch:.1f} % "
            f"speed mismatch ({tolerance.speed_mismatch_case})"
        )
        robust = mission.robust_margin
        print(
            f"  clearance kept: {100 * mission.obstacle_clearance:.1f} cm"
            + ("" if robust is None else f"; robust margin {100 * robust:.1f} cm")
        )
        if mission.robust_statics_margin is not None:
            print(
                f"  statics margins against the drones' errors: least "
                f"{mission.robust_statics_margin:.2f} N ({mission.robust_statics_limit})"
            )
        for k in (1, 2, 3):
            waypoints, plan = mission_file(k, "waypoints"), mission_file(k, "plan")
            print(f"  drone {k}: {out / waypoints}  {out / plan}")
        print(f"  MCAP log (Foxglove): {out / MCAP_FILE}")
        print(f"  profile plot: {out / PROFILE_FILE}")
    print(f"summary: {out / SUMMARY_FILE} ({time.perf_counter() - clock:.1f} s in all)")
    return 0 if outcome.status == "done" else 1


def register(commands: argparse._SubParsersAction) -> None:
    """Add ``plan`` to the ``flycrane`` command line (entry point ``flycrane.commands``)."""
    command = commands.add_parser("plan", help="plan a task and export missions, MCAP, plots")
    command.add_argument("task", nargs="?", help="task .json/.toml (default: Rescue defaults)")
    command.add_argument("--out", default="out", help="directory for the artifacts")
    command.set_defaults(handler=_cmd_plan)
