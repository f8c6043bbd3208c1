"""One attempt of :func:`~missions.trajectory.flight_plan.plan_flight`, which splits legs
until one passes: a timing of the stored waypoints, the flight ArduCopter makes of it, and
its check (steps 2 to 4 of :mod:`missions.trajectory.flight_plan`)."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from flycrane.model.cable_system import CableSystem
from flycrane.model.direct_kinematics import configuration_from_drone_positions
from flycrane.model.kinematics import matrix_from_tilt_torsion
from missions.autopilots.ardupilot import ArduCopterSettings
from missions.autopilots.speed_solver import FleetSpeeds, LegFlights, solve_fleet
from missions.options import MissionOptions
from missions.trajectory.motion import DroneMotion, formation_progress
from missions.trajectory.time_law import rotation_angles
from missions.trajectory.tracks import Track
from missions.trajectory.waypoints import LegCheck, SafetyCheck, StoredWaypoints, check_flight


def angular_floor(q: NDArray[np.float64], options: MissionOptions) -> NDArray[np.float64]:
    """Shortest leg durations allowed by the platform's angular rate limit (K-1,) [s]."""
    return rotation_angles(matrix_from_tilt_torsion(q[:, 3:6])) / options.max_angular_rate


@dataclass(frozen=True)
class ModelledFlight:
    """One timing of a set of waypoints, its modelled motion, and its check."""

    waypoints: StoredWaypoints
    fleet: FleetSpeeds
    motion: DroneMotion
    check: LegCheck  #: up to the raised goal
    times: NDArray[np.float64]  #: check times [s]
    progress: NDArray[np.float64]  #: the dense plan's time at each check time [s]
    set_down_safe: bool

    def passes(self, options: MissionOptions) -> bool:
        return bool(self.check.badness(options).max() <= 1.0) and self.set_down_safe


def model_flight(
    system: CableSystem,
    track: Track,
    waypoints: StoredWaypoints,
    validity: SafetyCheck,
    landing: SafetyCheck,
    options: MissionOptions,
    settings: ArduCopterSettings,
    flights: LegFlights,
) -> ModelledFlight:
    """Timing for ``waypoints``, the modelled motion, and its check every
    ``check_resolution`` (:mod:`missions.trajectory.flight_plan`, step 3); ``landing``
    judges the set-down leg; ``flights`` are those of the plan's earlier attempts."""
    fleet = solve_fleet(
        waypoints.drones,
        waypoints.planned,
        settings,
        options.max_drone_speed,
        angular_floor(waypoints.q, options),
        flights,
    )
    motion = DroneMotion.from_chains(fleet.flights, fleet.times)
    step = options.check_resolution
    dense_end = float(fleet.times[len(waypoints.indices) - 1])
    times = np.arange(0.0, dense_end + step / 2, step)
    flown = motion.at(times)
    progress = formation_progress(track.time, track.drones, flown)
    check = check_flight(system, track, flown, progress, validity)
    set_down_safe = True
    if len(fleet.times) > len(waypoints.indices):  # a set-down: collisions only
        during = np.arange(dense_end, float(fleet.times[-1]) + step / 2, step)
        rebuilt = configuration_from_drone_positions(
            system, motion.at(during), initial=np.repeat(waypoints.q[-2:-1], len(during), 0)
        )
        set_down_safe = bool(np.all(rebuilt.converged & landing(rebuilt.q)))
    return ModelledFlight(waypoints, fleet, motion, check, times, progress, set_down_safe)


def merge_early_legs(
    trial: ModelledFlight,
    attempt: Callable[[NDArray[np.int64]], ModelledFlight],
    options: MissionOptions,
) -> ModelledFlight:
    """Drop a waypoint next to a leg some drone flies early while that leaves fewer early
    legs and the check still passes: such legs are mostly the time law's slow ramps, which
    a longer leg flies at a settable speed (the autopilot accelerates and brakes by
    itself). The first and last dense waypoints stay."""
    for _ in range(len(trial.waypoints.indices)):
        early = trial.fleet.early
        if not early:
            break
        leg = early[0][1] - 1  # 0-based leg k runs from waypoint k to k + 1
        last = len(trial.waypoints.indices) - 1
        for drop in (leg + 1, leg):  # its end, else its start
            if not 0 < drop < last:
                continue
            candidate = attempt(np.delete(trial.waypoints.indices, drop))
            if len(candidate.fleet.early) < len(early) and candidate.passes(options):
                trial = candidate
                break
        else:
            break
    return trial
