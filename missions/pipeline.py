"""The whole job of a task: plan, smooth, time, reduce, annotate, export.

:func:`run_task` is what the service's workers and ``flycrane plan`` run. Every artifact
goes into ``out_dir``; the returned :class:`TaskOutcome` (plain data) says what happened
and where the files are. Not finding a path, or a path that cannot be flown safely with
straight legs, is an outcome (status "failed" with the reason), not an exception.
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from datetime import UTC, datetime
from functools import partial
from pathlib import Path
from typing import Any, Literal

import numpy as np

from flycrane.planning.planners import plan
from flycrane.planning.result import PlanningProgress
from flycrane.profiles import path_profile, plot_path_profile
from missions.annotations import annotate
from missions.builder import LegSpeeds, build_missions
from missions.formats import dumps, mission_json, qgc_plan, waypoints_text
from missions.geodesy import geodetic_from_enu
from missions.mcap_log import LogInputs, write_mcap
from missions.task import ResolvedTask, TaskSpec, resolve_task
from missions.timing_tolerance import timing_tolerance
from missions.tracks import track_from_path
from missions.waypoints import reduce_to_waypoints

logger = logging.getLogger(__name__)

#: Most samples the checks of one mission may take (twice its duration over
#: ``mission.check_resolution``: the timing tolerance flies the plan for up to twice its
#: length). Each sample holds drone positions and a reconstructed configuration in every
#: pass, so this bounds a worker's memory whatever the task (2.8 h of mission at 0.1 s).
MAX_CHECK_SAMPLES = 200_000

Status = Literal["done", "failed", "cancelled"]
Stage = Literal["planning", "generating"]


@dataclass(frozen=True)
class TaskOutcome:
    """What a task run produced. ``artifacts`` maps names to files relative to out_dir."""

    status: Status
    reason: str = ""
    planner_status: str = ""
    planner_statistics: dict[str, Any] = field(default_factory=dict)
    metrics: dict[str, float] | None = None
    mission: dict[str, Any] | None = None  #: waypoints, duration, deviations, tolerance
    artifacts: dict[str, str] = field(default_factory=dict)

    def as_dict(self) -> dict[str, Any]:
        return asdict(self)


def _write(out_dir: Path, name: str, text: str, artifacts: dict[str, str]) -> None:
    (out_dir / name).write_text(text, encoding="utf-8")
    artifacts[name.replace("/", "_")] = name


def run_task(
    task: TaskSpec,
    out_dir: str | Path,
    progress: Callable[[Stage, PlanningProgress | None], None] | None = None,
    should_stop: Callable[[], bool] | None = None,
    base_dir: Path | None = None,
    resolved: ResolvedTask | None = None,
) -> TaskOutcome:
    """Run a task end to end, writing its artifacts into ``out_dir``."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    resolved = resolved or resolve_task(task, base_dir)
    problem = resolved.problem
    report = (lambda stage, p=None: progress(stage, p)) if progress else (lambda *_: None)
    report("planning")
    planned = plan(
        problem.space,
        problem.validity,
        resolved.start,
        resolved.goal,
        task.planner,
        should_stop=should_stop,
        progress=lambda p: report("planning", p),
    )
    result = planned.result
    statistics = {**result.statistics.as_dict(), "smoothing_time": planned.smoothing_time}
    base = {"planner_status": result.status.value, "planner_statistics": statistics}
    # Every outcome carries the planner's status and statistics.
    outcome_of = partial(
        TaskOutcome, planner_status=result.status.value, planner_statistics=statistics
    )
    if not result.status.solved:
        status: Status = "cancelled" if result.status.value == "cancelled" else "failed"
        outcome = outcome_of(status, result.reason or result.status.value)
        _write(out, "summary.json", dumps(outcome.as_dict()), {})
        return outcome
    report("generating")
    artifacts: dict[str, str] = {}
    options, system = task.mission, problem.system
    _write(
        out,
        "path.json",
        dumps({"configurations": planned.path.tolist(), "raw_path": result.path.tolist()}),
        artifacts,
    )
    track = track_from_path(system, problem.space, planned.path, options)
    samples = 2.0 * float(track.time[-1]) / options.check_resolution
    if samples > MAX_CHECK_SAMPLES:
        reason = (
            f"mission generation: a {track.time[-1]:.0f} s mission checked every "
            f"{options.check_resolution:g} s needs {samples:.3g} samples, more than "
            f"{MAX_CHECK_SAMPLES}; raise mission.check_resolution or the speeds"
        )
        outcome = outcome_of("failed", reason, artifacts=artifacts)
        _write(out, "summary.json", dumps(outcome.as_dict()), {})
        return outcome
    # The plan keeps the scene's obstacle clearance c. The straight legs may use half of it;
    # the other half is left for the flight. The timing tolerance is judged on the real
    # obstacles, as a flown load is (docs/missions.md, "Clearance").
    clearance = problem.scene.collision.obstacle_clearance
    legs = problem.validity.with_clearance(clearance / 2)
    waypoints = reduce_to_waypoints(system, track, legs.is_safe, options)
    metrics = planned.metrics.as_dict() if planned.metrics else None
    if not waypoints.ok:
        outcome = outcome_of(
            "failed",
            f"mission generation: {waypoints.reason}",
            metrics=metrics,
            artifacts=artifacts,
        )
        _write(out, "summary.json", dumps(outcome.as_dict()), {})
        return outcome
    annotations = annotate(system, waypoints.time, waypoints.q)
    missions = build_missions(waypoints, options)
    flown = problem.validity.with_clearance(0.0)
    tolerance = timing_tolerance(system, track, waypoints, flown.is_safe, options)
    lat, lon, alt = geodetic_from_enu(waypoints.drones, options.origin)
    mission_summary = {
        "waypoints": len(waypoints.time),
        "duration": float(waypoints.time[-1]),
        "max_platform_deviation": waypoints.max_platform_deviation,
        "max_cable_length_error": waypoints.max_cable_length_error,
        "timing_tolerance": tolerance.as_dict(),
        "slow_legs": LegSpeeds.of(waypoints).slow_legs(),
        "items_per_drone": [len(m.items) for m in missions],
    }
    tracks = {
        "time": waypoints.time.tolist(),
        "configurations": waypoints.q.tolist(),
        "drones_enu": waypoints.drones.tolist(),
        "drones_wgs84": np.stack([lat, lon, alt], axis=-1).tolist(),
        "leg_speeds": waypoints.leg_speeds.tolist(),
        "annotations": annotations.records(),
        "timing_tolerance": tolerance.as_dict(),
        "dense": {"time": track.time.tolist(), "configurations": track.q.tolist()},
    }
    _write(out, "tracks.json", dumps(tracks), artifacts)
    for mission in missions:
        stem = f"drone{mission.drone}"
        _write(out, f"{stem}.waypoints", waypoints_text(mission), artifacts)
        _write(out, f"{stem}.plan", dumps(qgc_plan(mission, options.max_drone_speed)), artifacts)
        _write(out, f"{stem}.mission.json", dumps(mission_json(mission)), artifacts)
    start = options.start_time_utc or datetime.now(UTC)
    write_mcap(
        out / "mission.mcap",
        LogInputs(
            system=system,
            scene=problem.scene,
            track=track,
            annotations=annotations,
            missions=missions,
            options=options,
            start_ns=int(start.timestamp() * 1e9),
            metadata={
                "system": system.spec.model_dump(mode="json"),
                "scene": problem.scene.model_dump(mode="json"),
                "planner": base,
                "mission": mission_summary,
            },
        ),
    )
    artifacts["mcap"] = "mission.mcap"
    profile = path_profile(system, problem.space, planned.path)
    plot_path_profile(
        profile,
        system,
        out / "profile.png",
        title=f"{task.name or problem.scene.name}: tensions and thrusts",
    )
    artifacts["profile"] = "profile.png"
    outcome = outcome_of("done", "", metrics=metrics, mission=mission_summary, artifacts=artifacts)
    _write(out, "summary.json", dumps(outcome.as_dict()), artifacts)
    logger.info("task done in %s: %d waypoints", out, len(waypoints.time))
    return outcome
