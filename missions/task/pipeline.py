"""The whole job of a task: plan, build the missions, write the directory.

:func:`run_task` is what the service's workers and ``flycrane plan`` run, in three phases:
planning (:func:`flycrane.planning.planners.plan`), mission building
(:func:`missions.task.build.build`) and writing (:class:`~missions.task.directory.
TaskDirectory`, the MCAP log and the profile plot). Not finding a path, or a path that
cannot be flown safely, is an outcome (status "failed" with the reason), not an exception:
every phase ends in the one failure exit, which writes ``summary.json``. A path whose
missions fail their check is planned again with another seed while the budget lasts; with
``mission.robust_clearance`` (the default), a path the drones' errors could bring closer
to an obstacle than it keeps is planned again with a larger clearance, and one whose
statics margins they could exhaust with another seed.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any, Literal

from flycrane.planning.planners import plan
from flycrane.planning.result import PlanningProgress
from flycrane.quantities import MAX_SEED
from missions.task.build import UnflyablePath, build
from missions.task.directory import TaskDirectory
from missions.task.documents import Status, TaskOutcome, raised_clearance
from missions.task.limits import Cancelled, MissionFailure, PhaseLimits, TaskEnded, ending
from missions.task.resolve import ResolvedTask, resolve_raised, resolve_task
from missions.task.spec import TaskSpec
from missions.task.write import write_files

logger = logging.getLogger(__name__)

Stage = Literal["planning", "generating"]


#: Most plans a task tries when the mission made of a path fails its check.
MAX_PLANS = 4
#: Most plans with a raised clearance (``mission.robust_clearance``), and how much more
#: than the robust margin's shortfall [m] each raises it.
MAX_ROBUST_PLANS, ROBUST_STEP = 3, 0.01


def run_task(
    task: TaskSpec,
    out_dir: str | Path,
    progress: Callable[[Stage, PlanningProgress | None], None] | None = None,
    should_stop: Callable[[], bool] | None = None,
    base_dir: Path | None = None,
    resolved: ResolvedTask | None = None,
) -> TaskOutcome:
    """Run a task end to end, writing its artifacts into ``out_dir``.

    A path whose missions fail their check (:class:`~missions.task.build.UnflyablePath`)
    is planned again with the next seed, up to :data:`MAX_PLANS` plans, while the planning
    budget (``planner.time_budget``, shared by the plans) lasts; the outcome lists what was
    tried (``attempts``) and ``task.json`` the seed that made the missions. With
    ``mission.robust_clearance``, a path whose robust margin is below zero is planned
    again keeping that much more clearance, up to :data:`MAX_ROBUST_PLANS` times, and one
    whose statics margins the drones' errors could exhaust (its robust statics margin
    below zero) with the next seed, as an unflyable one, while the budget lasts; the last
    path is built, and the summary gives its margins."""
    directory = TaskDirectory(out_dir).create()
    resolved = resolved or resolve_task(task, base_dir)
    report = progress or (lambda *_: None)
    planning_ends = time.monotonic() + task.planner.time_budget
    limits: PhaseLimits | None = None  # the making's budget, from the first path on
    attempts: list[dict[str, Any]] = []
    seed, robust_margin, statics = task.planner.seed, None, None
    while True:
        report("planning", None)
        options = task.planner.model_copy(
            update={"seed": seed, "time_budget": max(planning_ends - time.monotonic(), 1e-3)}
        )
        planned = plan(
            resolved.problem.space,
            resolved.checkers.planning,
            resolved.start,
            resolved.goal,
            options,
            should_stop=should_stop,
            progress=lambda p: report("planning", p),
            algorithm=resolved.algorithm,
            robust=resolved.robust,
        )
        result = planned.result
        statistics = {**result.statistics.as_dict(), "smoothing_time": planned.smoothing_time}
        outcome = TaskOutcome(
            "failed",
            planner_status=result.status.value,
            planner_statistics=statistics,
            attempts=tuple(attempts),
        )
        try:
            if not result.status.solved:
                cancelled = result.status.value == "cancelled"
                reason = result.reason or result.status.value
                if given_up := _given_up(attempts):
                    reason = f"{reason} (after {given_up} unflyable path(s))"
                raise TaskEnded("cancelled" if cancelled else "failed", reason)
            if task.mission.robust_clearance:
                robust_margin = resolved.robust.margin(planned.path, resolved.problem.space)
                again = None
                if robust_margin < 0 and len(attempts) - _given_up(attempts) < MAX_ROBUST_PLANS:
                    again = resolve_raised(task, base_dir, resolved, robust_margin, ROBUST_STEP)
                if again is not None and time.monotonic() < planning_ends:
                    resolved, clearance = again
                    attempts.append({"seed": seed, "clearance": clearance, "reason": (
                        f"robust margin {robust_margin:.3f} m: planned again keeping "
                        f"{clearance:.3f} m")})  # fmt: skip
                    continue
                statics = resolved.robust_statics(planned.path).least()[:2]
                another = _given_up(attempts) + 1 < MAX_PLANS
                if statics[0] < 0 and another and time.monotonic() < planning_ends:
                    attempts.append({"seed": seed, "reason": (
                        f"robust statics margin {statics[0]:.3f} N ({statics[1]}): planned "
                        "again with the next seed")})  # fmt: skip
                    seed = (seed + 1) % (MAX_SEED + 1)
                    continue
            report("generating", None)
            outcome = TaskOutcome(**{**outcome.__dict__, "metrics": planned.metrics})
            used = resolved.self_contained()
            directory.write_task(used.model_copy(update={"planner": used.planner.model_copy(
                update={"seed": seed})}), resolved.scene_dir)  # fmt: skip
            directory.write_path(planned.path, result.path)
            limits = limits or PhaseLimits.starting_now(should_stop, task.planner.time_budget)
            try:
                built = build(resolved, planned.path, limits, robust_margin, statics)
            except UnflyablePath as unflyable:
                attempts.append({"seed": seed, "reason": str(unflyable)})
                if _given_up(attempts) < MAX_PLANS and time.monotonic() < planning_ends:
                    logger.info("seed %d: %s; planning again", seed, unflyable)
                    seed = (seed + 1) % (MAX_SEED + 1)
                    continue
                tried = ", ".join(str(a["seed"]) for a in attempts if not raised_clearance(a))
                reason = f"mission generation: {unflyable} (seeds tried: {tried})"
                raise TaskEnded("failed", reason) from None
            write_files(directory, resolved, planned, built, limits)
        except (TaskEnded, MissionFailure, Cancelled) as failure:
            status, reason = ending(failure)
            return directory.write_summary(_failure(directory, outcome, status, reason, attempts))
        break
    done = TaskOutcome(
        **{
            **outcome.__dict__,
            "status": "done",
            "mission": built.summary,
            "artifacts": dict(directory.artifacts),
            "attempts": tuple(attempts),
        }
    )
    logger.info("task done in %s: %d waypoints", directory.path, built.summary.waypoints)
    return directory.write_summary(done)


def _given_up(attempts: list[dict[str, Any]]) -> int:
    """How many of the task's paths were given up for another seed (not a raised
    clearance)."""
    return sum(not raised_clearance(a) for a in attempts)


def _failure(
    directory: TaskDirectory,
    outcome: TaskOutcome,
    status: Status,
    reason: str,
    attempts: list[dict[str, Any]],
) -> TaskOutcome:
    """The one failure exit: the outcome so far with its status, reason, attempts, files."""
    return TaskOutcome(
        **{
            **outcome.__dict__,
            "status": status,
            "reason": reason,
            "artifacts": dict(directory.artifacts),
            "attempts": tuple(attempts),
        }
    )
