"""Mission building: from a planned path to the timed, checked missions of three drones.

The dense track and its time law (:mod:`missions.trajectory.tracks`), the flyable plan with
its modelled flight (:mod:`missions.trajectory.flight_plan`), the per-waypoint annotations,
the timing tolerance and the per-drone MAVLink missions. A path that cannot be made into
missions that keep the load safe ends the task as failed (:class:`MissionFailure`), with
the reason.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from flycrane.errors import FlyCraneError
from flycrane.model.kinematics import drone_positions_from_configuration
from missions.export.builder import HOLD_SEQ, RELEASE_SEQ, build_missions
from missions.export.items import DroneMission
from missions.geodesy import geodetic_from_enu
from missions.position_error import position_error_model
from missions.task.directory import MissionSummary, Release, Tracks
from missions.task.resolve import ResolvedTask
from missions.trajectory.annotations import Annotations, annotate
from missions.trajectory.drone_trajectory import DroneTrajectory
from missions.trajectory.flight_plan import FlightPlan, plan_flight
from missions.trajectory.timing_tolerance import timing_tolerance
from missions.trajectory.tracks import Track, track_from_path

#: Most samples the checks of one mission may take (twice its duration over
#: ``mission.check_resolution``: the timing tolerance flies the plan for up to twice its
#: length). Each sample holds drone positions and a reconstructed configuration in every
#: pass, so this bounds a worker's memory whatever the task (2.8 h of mission at 0.1 s).
MAX_CHECK_SAMPLES = 200_000


class MissionFailure(FlyCraneError):
    """The path cannot be made into missions that keep the load safe; the message says
    why."""


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


def build(resolved: ResolvedTask, path: NDArray[np.float64]) -> BuiltMissions:
    """The missions of the planned ``path`` (M, 9).

    Raises
    ------
    MissionFailure
        The checks would exceed :data:`MAX_CHECK_SAMPLES`, or no flyable plan keeps the load
        safe.
    """
    task, problem, checkers = resolved.task, resolved.problem, resolved.checkers
    options, system = task.mission, problem.system
    dense = track_from_path(system, problem.space, path, options)
    samples = 2.0 * float(dense.time[-1]) / options.check_resolution
    if samples > MAX_CHECK_SAMPLES:
        raise MissionFailure(
            f"a {dense.time[-1]:.0f} s mission checked every {options.check_resolution:g} s "
            f"needs {samples:.3g} samples, more than {MAX_CHECK_SAMPLES}; raise "
            "mission.check_resolution or the speeds"
        )
    set_down = resolved.set_down
    # a set-down may touch its surfaces, nothing else
    landing = checkers.real.without(set_down.surfaces).is_safe if set_down else None
    flight = plan_flight(
        system, dense, checkers.legs.is_safe, options, set_down=set_down, landing=landing
    )
    if not flight.ok:
        raise MissionFailure(flight.reason)
    track = flight.retimed(dense)
    annotations = annotate(system, flight.time, flight.q)
    missions = build_missions(flight, options)
    tolerance = timing_tolerance(system, dense, flight, checkers.real.is_safe, options)
    lat, lon, alt = geodetic_from_enu(flight.drones, options.origin)
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
        position_error=position_error_model(options.position_error),
        lift_off=resolved.lift_off,
        set_down=flight.set_down,
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
