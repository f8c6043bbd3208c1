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

from flycrane.analysis.profiles import path_profile, plot_path_profile
from flycrane.model.kinematics import drone_positions_from_configuration
from flycrane.planning.planners import plan
from flycrane.planning.result import PlanningProgress
from missions.export.builder import HOLD_SEQ, RELEASE_SEQ, build_missions
from missions.export.formats import dumps, mission_json, qgc_plan, waypoints_text
from missions.export.mcap_log import LogInputs, write_mcap
from missions.export.parameter_file import parameter_file_text
from missions.geodesy import geodetic_from_enu
from missions.position_error import position_error_model
from missions.task.spec import ResolvedTask, TaskSpec, resolve_task
from missions.trajectory.annotations import annotate
from missions.trajectory.flight_plan import SetDown, plan_flight
from missions.trajectory.timing_tolerance import timing_tolerance
from missions.trajectory.tracks import track_from_path

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


#: The head of every exported ``.parm`` file.
PARM_HEADER = """FlyCrane: parameters every drone of this mission must have (ArduCopter 4.5).
Load them before the flight; the upload reads them back and reports any that differ.
Never load BARO_GND_TEMP on a powered vehicle (SITL's altitude jumped by 27 m)."""


def _self_contained(task: TaskSpec, resolved: ResolvedTask) -> dict[str, Any]:
    """The task with its system, scene, start, goal and planner written out, so that the
    task's directory alone says what was planned (the flight report reads it)."""
    problem = resolved.problem
    algorithm = task.planner.algorithm_for(problem.validity.has_meshes)
    return task.model_copy(
        update={
            "planner": task.planner.model_copy(update={"algorithm": algorithm}),
            "system": problem.system.spec,
            "scene": problem.scene,
            "start": tuple(float(v) for v in resolved.start),
            "goal": tuple(float(v) for v in resolved.goal),
        }
    ).model_dump(mode="json")


def _set_down_summary(set_down: SetDown | None) -> dict[str, Any] | None:
    """A set-down as tracks.json and summary.json give it."""
    if set_down is None:
        return None
    return {**set_down.leg.as_dict(), "start_time": set_down.start, "end_time": set_down.end}


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
    _write(out, "task.json", dumps(_self_contained(task, resolved)), artifacts)
    _write(
        out,
        "path.json",
        dumps({"configurations": planned.path.tolist(), "raw_path": result.path.tolist()}),
        artifacts,
    )
    dense = track_from_path(system, problem.space, planned.path, options)
    samples = 2.0 * float(dense.time[-1]) / options.check_resolution
    if samples > MAX_CHECK_SAMPLES:
        reason = (
            f"mission generation: a {dense.time[-1]:.0f} s mission checked every "
            f"{options.check_resolution:g} s needs {samples:.3g} samples, more than "
            f"{MAX_CHECK_SAMPLES}; raise mission.check_resolution or the speeds"
        )
        outcome = outcome_of("failed", reason, artifacts=artifacts)
        _write(out, "summary.json", dumps(outcome.as_dict()), {})
        return outcome
    # The plan keeps the scene's obstacle clearance c. The legs may use half of it; the
    # other half is left for the flight. The timing tolerance is judged on the real
    # obstacles, as a flown load is (docs/missions.md, "Clearance").
    clearance = problem.scene.collision.obstacle_clearance
    legs = problem.validity.with_clearance(clearance / 2)
    set_down = resolved.set_down
    landing = None
    if set_down is not None:  # the set-down may touch its surfaces, nothing else
        landing = problem.validity.with_clearance(0.0).without(set_down.surfaces).is_safe
    flight = plan_flight(system, dense, legs.is_safe, options, set_down=set_down, landing=landing)
    metrics = planned.metrics.as_dict() if planned.metrics else None
    if not flight.ok:
        outcome = outcome_of(
            "failed",
            f"mission generation: {flight.reason}",
            metrics=metrics,
            artifacts=artifacts,
        )
        _write(out, "summary.json", dumps(outcome.as_dict()), {})
        return outcome
    track = flight.retimed(dense)
    annotations = annotate(system, flight.time, flight.q)
    missions = build_missions(flight, options)
    flown = problem.validity.with_clearance(0.0)
    tolerance = timing_tolerance(system, dense, flight, flown.is_safe, options)
    lat, lon, alt = geodetic_from_enu(flight.drones, options.origin)
    mission_summary = {
        "waypoints": len(flight.time),
        "duration": flight.duration,
        "max_platform_deviation": flight.max_platform_deviation,
        "max_cable_length_error": flight.max_cable_length_error,
        "max_tracking_deviation": flight.max_tracking_deviation,
        "timing_tolerance": tolerance.as_dict(),
        "early_legs": [list(e) for e in flight.early],
        "items_per_drone": [len(m.items) for m in missions],
        "release": {"hold_seq": HOLD_SEQ, "release_seq": RELEASE_SEQ},
        "obstacle_clearance": problem.scene.collision.obstacle_clearance,
        "position_error": position_error_model(options.position_error).model_dump(),
        "lift_off": resolved.lift_off.as_dict() if resolved.lift_off else None,
        "set_down": _set_down_summary(flight.set_down),
    }
    tracks = {
        "time": flight.time.tolist(),
        "configurations": flight.q.tolist(),
        "drones_enu": drone_positions_from_configuration(system, flight.q).tolist(),
        "drones_stored_enu": flight.drones.tolist(),  # as ArduPilot stores the waypoints
        "drones_wgs84": np.stack([lat, lon, alt], axis=-1).tolist(),
        "speed_limits": [[asdict(limit) for limit in row] for row in flight.limits],
        "annotations": annotations.records(),
        "timing_tolerance": tolerance.as_dict(),
        "dense": {"time": track.time.tolist(), "configurations": track.q.tolist()},
        "motion": flight.motion.as_dict(),
        "vehicle_motion": flight.vehicles.as_dict(),
        "lift_off": resolved.lift_off.as_dict() if resolved.lift_off else None,
        "set_down": _set_down_summary(flight.set_down),
    }
    _write(out, "tracks.json", dumps(tracks), artifacts)
    parameters = flight.settings.parameters()
    for mission in missions:
        stem = f"drone{mission.drone}"
        _write(out, f"{stem}.waypoints", waypoints_text(mission), artifacts)
        _write(out, f"{stem}.plan", dumps(qgc_plan(mission, options.max_drone_speed)), artifacts)
        _write(out, f"{stem}.mission.json", dumps(mission_json(mission)), artifacts)
        _write(
            out,
            f"{stem}.parm",
            parameter_file_text(parameters, flight.settings.reasons(), PARM_HEADER),
            artifacts,
        )
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
    logger.info("task done in %s: %d waypoints", out, len(flight.time))
    return outcome
