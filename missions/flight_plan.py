"""The flyable plan: timed spline waypoints, each drone's speed limits per leg, and the
motion ArduCopter will fly with them (design.md section 9, ``missions.autopilots``).

1. **Waypoints**: the fewest whose straight legs keep the load safe
   (:func:`missions.waypoints.reduce_to_waypoints`), as the autopilot stores them
   (:func:`stored_positions`).
2. **Timing**: waypoint times and per-drone limits with which the modelled flights reach
   every waypoint together (:func:`missions.autopilots.speed_solver.solve_fleet`), no
   faster than the drone speed and platform angular rate limits allow.
3. **Check**: the load reconstructed from the three *modelled* drone positions every
   ``check_resolution`` seconds, against the plan at the formation's progress (the dense
   sample nearest the three drones: a delay all three share is harmless, a difference
   between them is not), must pass the same checks as the straight legs did; where it fails
   worst, the leg is split at the dense sample there, and timing and check run again.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from flycrane.cable_system import CableSystem
from flycrane.kinematics import matrix_from_tilt_torsion
from missions.autopilots.ardupilot import ArduCopterSettings
from missions.autopilots.speed_solver import solve_fleet
from missions.autopilots.spline import SpeedLimits
from missions.geodesy import (
    DEGREE_UNIT,
    ardupilot_altitude,
    degrees_to_int,
    enu_from_geodetic,
    geodetic_from_enu,
)
from missions.motion import DroneMotion
from missions.options import MissionOptions
from missions.tracks import Track, rotation_angles
from missions.waypoints import Validity, check_flight, reduce_to_waypoints

#: Most splits of legs whose modelled flight failed its check, before giving up.
MAX_SPLITS = 40


@dataclass(frozen=True)
class FlightPlan:
    """Timed spline waypoints with each drone's speed limits (module docstring)."""

    ok: bool
    reason: str
    indices: NDArray[np.int64]  #: (K,) samples of the dense track used as waypoints
    time: NDArray[np.float64]  #: (K,) mission time of each waypoint [s from the release]
    q: NDArray[np.float64]  #: (K, 9) planned configurations at the waypoints
    drones: NDArray[np.float64]  #: (K, 3, 3) waypoints as the autopilot stores them [m]
    limits: tuple[tuple[SpeedLimits, ...], ...]  #: [drone][leg]
    motion: DroneMotion  #: what the autopilots will fly
    track_time: NDArray[np.float64]  #: (K,) the dense plan's time at each waypoint
    settings: ArduCopterSettings
    early: tuple[tuple[int, int], ...]  #: (drone, leg) flown faster than planned (1-based)
    max_platform_deviation: float  #: over the modelled flight [m]
    max_cable_length_error: float  #: [m]

    @property
    def duration(self) -> float:
        return float(self.time[-1])

    def progress_time(self, t: NDArray[np.float64]) -> NDArray[np.float64]:
        """The dense plan's time at mission times ``t``: linear between waypoints."""
        return np.interp(t, self.time, self.track_time)

    def retimed(self, track: Track) -> Track:
        """The dense plan on mission time (the inverse of :meth:`progress_time`)."""
        return Track(np.interp(track.time, self.track_time, self.time), track.q, track.drones)


def stored_positions(enu: NDArray[np.float64], options: MissionOptions) -> NDArray[np.float64]:
    """ENU positions (..., 3) as ArduPilot flies them: latitude and longitude rounded to
    1e-7 degree (about 1 cm), altitudes truncated to whole centimetres. Speeds planned for
    unrounded positions would be off by the rounding: on a leg that moves centimetres in one
    direction, by tens of percent in that direction's limit."""
    origin = options.origin
    lat, lon, amsl = geodetic_from_enu(enu, origin)
    relative = options.altitude_frame == "relative"
    height = np.asarray(enu, dtype=float)[..., 2] if relative else amsl
    stored = ardupilot_altitude(height)
    return enu_from_geodetic(
        degrees_to_int(lat) * DEGREE_UNIT,
        degrees_to_int(lon) * DEGREE_UNIT,
        stored + origin.altitude if relative else stored,
        origin,
    )


def _angular_floor(q: NDArray[np.float64], options: MissionOptions) -> NDArray[np.float64]:
    """Shortest leg durations allowed by the platform's angular rate limit (K-1,) [s]."""
    return rotation_angles(matrix_from_tilt_torsion(q[:, 3:6])) / options.max_angular_rate


def plan_flight(
    system: CableSystem,
    track: Track,
    validity: Validity,
    options: MissionOptions,
    settings: ArduCopterSettings | None = None,
) -> FlightPlan:
    """Waypoints, timing and limits for the three drones (module docstring)."""
    settings = settings or ArduCopterSettings.for_acceleration(options.autopilot_acceleration)
    straight = reduce_to_waypoints(system, track, validity, options)
    indices = straight.indices
    reason = straight.reason
    for _ in range(MAX_SPLITS + 1):
        drones = stored_positions(track.drones[indices], options)
        fleet = solve_fleet(
            drones,
            track.time[indices],
            settings,
            options.max_drone_speed,
            _angular_floor(track.q[indices], options),
        )
        motion = DroneMotion.from_chains(fleet.flights, fleet.times)
        track_time = track.time[indices]
        times = np.arange(
            0.0, motion.duration + options.check_resolution / 2, options.check_resolution
        )
        progress = np.interp(times, fleet.times, track_time)
        check = check_flight(system, track, motion.at(times), progress, validity)
        badness = np.maximum(
            check.platform_deviation / options.max_platform_deviation,
            check.cable_length_error / options.max_cable_length_error,
        )
        badness = np.where(check.valid, badness, np.inf)
        if badness.max() <= 1.0 or not straight.ok:
            break
        worst = float(progress[int(np.argmax(badness))])
        sample = int(np.clip(np.searchsorted(track.time, worst), 1, len(track.time) - 2))
        if sample in indices:
            reason = (
                f"the modelled flight fails its check at {times[int(np.argmax(badness))]:.2f} s, "
                "on a leg that cannot be split further"
            )
            break
        indices = np.sort(np.append(indices, sample))
    else:
        reason = f"the modelled flight still fails its check after {MAX_SPLITS} splits"
    return FlightPlan(
        ok=straight.ok and not reason,
        reason=reason,
        indices=indices,
        time=fleet.times,
        q=track.q[indices],
        drones=drones,
        limits=fleet.limits,
        motion=motion,
        track_time=track_time,
        settings=settings,
        early=fleet.early,
        max_platform_deviation=float(check.platform_deviation.max()),
        max_cable_length_error=float(check.cable_length_error.max()),
    )
