"""Mission building: from a planned path to the timed, checked missions of three drones.

The dense track and its time law (:mod:`missions.trajectory.tracks`), the flyable plan with
its modelled flight (:mod:`missions.trajectory.flight_plan`), the per-waypoint annotations,
the timing tolerance and the per-drone MAVLink missions. A path that cannot be made into
missions that keep the load safe ends the task as failed (:class:`UnflyablePath`), with
the reason.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from flycrane.model.kinematics import drone_positions_from_configuration
from missions.export.builder import HOLD_SEQ, RELEASE_SEQ, build_missions
from missions.export.items import DroneMission
from missions.geodesy import geodetic_from_enu
from missions.options import MAX_MISSION_DURATION_S
from missions.task.documents import MissionSummary, Release, Tracks
from missions.task.limits import MissionFailure, PhaseLimits
from missions.task.resolve import ResolvedTask
from missions.trajectory.annotations import Annotations, annotate
from missions.trajectory.drone_trajectory import DroneTrajectory
from missions.trajectory.flight_plan import FlightPlan, plan_flight
from missions.trajectory.timing_tolerance import timing_tolerance
from missions.trajectory.tracks import Track, least_duration, track_from_path

#: Most samples the checks of one mission may take (twice its duration over
#: ``mission.check_resolution``: the timing tolerance flies the plan for up to twice its
#: length). Each sample holds drone positions and a reconstructed configuration in every
#: pass, so this bounds a worker's memory whatever the task (2.8 h of mission at 0.1 s).
MAX_CHECK_SAMPLES = 200_000


class UnflyablePath(MissionFailure):
    """No flyable plan of this path keeps the load safe (another path may: the pipeline
    plans again)."""


def _check_duration(duration: float, bound: str) -> None:
    if duration > MAX_MISSION_DURATION_S:
        raise MissionFailure(
            f"the path's mission would last {bound + ' ' if bound else ''}{duration:.0f} s, "
            f"more than the {MAX_MISSION_DURATION_S:.0f} s a mission may last; raise the "
            "mission's speeds"
        )


@dataclass(frozen=True)
class BuiltMissions:
    """Everything the writing phase exports."""

    flight: FlightPlan
    track: Track  #: the dense plan on mission time
    annotations: Annotations
    missions: tuple[DroneMission, ...]
    tracks: Tracks
    summary: MissionSummary
    trajectory: DroneTrajectory  #: each drone's time law, for executors that stream it


def build(
    resolved: ResolvedTask,
    path: NDArray[np.float64],
    limits: PhaseLimits | None = None,
    robust_margin: float | None = None,
    robust_statics: tuple[float, str] | None = None,
) -> BuiltMissions:
    """The missions of the planned ``path`` (M, 9). ``limits`` are checked between the
    phases and before every safety check of the long ones (the flight plan, the timing
    tolerance), so that a cancel or the time budget reaches the work wherever it is;
    ``robust_margin``, the path's where measured, and its robust statics margin and
    the margin it is (``robust_statics``, measured here unless given) go to the summary.

    Raises
    ------
    MissionFailure
        The mission would last longer than :data:`~missions.options.MAX_MISSION_DURATION_S`
        or its checks take more than :data:`MAX_CHECK_SAMPLES`, no flyable plan keeps the
        load safe, or the making went past ``limits``' deadline.
    Cancelled
        ``limits.should_stop`` said so.
    """
    task, problem, checkers = resolved.task, resolved.problem, resolved.checkers
    options, system = task.mission, problem.system
    stop = limits or PhaseLimits()
    _check_duration(least_duration(system, path, options), "at least")
    dense = track_from_path(system, problem.space, path, options)
    _check_duration(float(dense.time[-1]), "")
    samples = 2.0 * float(dense.time[-1]) / options.check_resolution
    if samples > MAX_CHECK_SAMPLES:
        raise MissionFailure(
            f"a {dense.time[-1]:.0f} s mission checked every {options.check_resolution:g} s "
            f"needs {samples:.3g} samples, more than {MAX_CHECK_SAMPLES}; raise "
            "mission.check_resolution or the speeds"
        )
    set_down = resolved.set_down
    # a set-down may touch its surfaces, nothing else
    landing = stop.wrap(checkers.real.without(set_down.surfaces).is_safe) if set_down else None
    stop.check()
    flight = plan_flight(
        system, dense, stop.wrap(checkers.legs.is_safe), options, set_down=set_down,
        landing=landing,
    )  # fmt: skip
    if not flight.ok:
        raise UnflyablePath(flight.reason)
    stop.check()
    track = flight.retimed(dense)
    annotations = annotate(system, flight.time, flight.q)
    missions = build_missions(flight, options)
    tolerance = timing_tolerance(system, dense, flight, stop.wrap(checkers.real.is_safe), options)
    stop.check()
    lat, lon, alt = geodetic_from_enu(flight.drones, options.origin)
    # measured here, after the checks that bound the work, unless the pipeline has
    statics, limit = robust_statics or resolved.robust_statics(path).least()[:2]
    summary = MissionSummary(
        waypoints=len(flight.time),
        duration=flight.duration,
        max_platform_deviation=flight.max_platform_deviation,
        max_cable_length_error=flight.max_cable_length_error,
        max_tracking_deviation=flight.max_tracking_deviation,
        timing_tolerance=tolerance,
        early_legs=flight.early,
        items_per_drone=tuple(len(m.items) for m in missions),
        release=Release(hold_seq=HOLD_SEQ, release_seq=RELEASE_SEQ),
        obstacle_clearance=problem.scene.collision.obstacle_clearance,
        position_error=resolved.position_error,
        lift_off=resolved.lift_off,
        set_down=flight.set_down,
        robust_statics_margin=statics,
        robust_statics_limit=limit,
        robust_margin=robust_margin,
    )
    tracks = Tracks(
        time=flight.time,
        configurations=flight.q,
        drones_enu=drone_positions_from_configuration(system, flight.q),
        drones_stored_enu=flight.drones,
        drones_wgs84=np.stack([lat, lon, alt], axis=-1),
        speed_limits=flight.limits,
        annotations=tuple(annotations.records()),
        timing_tolerance=tolerance,
        dense_time=track.time,
        dense_configurations=track.q,
        motion=flight.motion,
        vehicle_motion=flight.vehicles,
        lift_off=resolved.lift_off,
        set_down=flight.set_down,
    )
    trajectory = DroneTrajectory.of_plan(dense, options, resolved.set_down)
    return BuiltMissions(flight, track, annotations, tuple(missions), tracks, summary, trajectory)
