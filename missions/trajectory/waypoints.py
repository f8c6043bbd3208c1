"""Timed waypoints shared by the three drones, with straight legs that keep the load safe.

Between two waypoints each drone flies a straight line at constant speed (what an autopilot
does). The platform then hangs wherever the three interpolated drone positions put it: we
reconstruct that configuration (direct kinematics, started from the planned one) every
``check_resolution`` seconds and require, along every leg,

- the reconstructed configuration valid (the task's validity: feasible, collision-free);
- the platform point P within ``max_platform_deviation`` of the planned one;
- the *cable-length error* within ``max_cable_length_error``: the largest
  ``| |A_lin - b_planned| - l_i |``, i.e. how far the straight legs pull the drones off
  the planned cable geometry (the reconstruction absorbs it; this bounds how much);
- the leg no longer than ``max_leg_duration``.

The reduction starts from one leg over the whole track and splits a failing leg at the
check time where it fails worst (the sample nearest to it), recursively. A leg that fails
between two consecutive dense samples cannot be split further: the reduction then reports
failure as a status.

The waypoints a mission flies are then those positions as the autopilot stores them
(:func:`stored_positions`): MAVLink's integer coordinates round them to about a centimetre.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from flycrane.model.cable_system import CABLE_DRONE, CableSystem
from flycrane.model.direct_kinematics import configuration_from_drone_positions
from flycrane.model.kinematics import (
    drone_positions_from_configuration,
    platform_points_from_configuration,
)
from missions.geodesy import (
    DEGREE_UNIT,
    ardupilot_altitude,
    degrees_to_int,
    enu_from_geodetic,
    geodetic_from_enu,
)
from missions.options import MissionOptions
from missions.trajectory.tracks import Track
from missions.trajectory.vertical_legs import VerticalLeg

#: Whether each configuration (N, 9) keeps the load safe (N,): a validity checker's
#: ``is_safe`` at the clearance a check is judged by.
SafetyCheck = Callable[[NDArray[np.float64]], NDArray[np.bool_]]


@dataclass(frozen=True)
class LegCheck:
    """What one leg does to the load, at its check times."""

    valid: NDArray[np.bool_]  #: (C,) reconstructed configuration valid and converged
    platform_deviation: NDArray[np.float64]  #: (C,) |P_rec - P_plan| [m]
    cable_length_error: NDArray[np.float64]  #: (C,) [m]
    times: NDArray[np.float64]  #: (C,) check times [s]
    q: NDArray[np.float64]  #: (C, 9) reconstructed configurations

    def badness(self, options: MissionOptions) -> NDArray[np.float64]:
        """(C,) the larger of the platform deviation and the cable-length error over its
        bound, +inf where the configuration is not valid: the check passes where <= 1."""
        badness = np.maximum(
            self.platform_deviation / options.max_platform_deviation,
            self.cable_length_error / options.max_cable_length_error,
        )
        return np.where(self.valid, badness, np.inf)


@dataclass(frozen=True)
class WaypointPlan:
    """The reduced mission: K waypoints with their time, configuration and drone positions."""

    ok: bool  #: False if some leg could not be made safe (see ``reason``)
    indices: NDArray[np.int64]  #: (K,) dense-track samples used as waypoints
    time: NDArray[np.float64]  #: (K,) [s]
    q: NDArray[np.float64]  #: (K, 9) planned configurations at the waypoints
    drones: NDArray[np.float64]  #: (K, 3, 3) drone positions [m]
    max_platform_deviation: float  #: over all check points [m]
    max_cable_length_error: float  #: over all check points [m]
    reason: str = ""


def drone_positions_at(
    waypoint_time: NDArray, waypoint_drones: NDArray, t: NDArray
) -> NDArray[np.float64]:
    """Positions (len(t), 3, 3) of drones flying straight, constant-speed legs."""
    t = np.clip(np.asarray(t, dtype=float), waypoint_time[0], waypoint_time[-1])
    k = np.clip(np.searchsorted(waypoint_time, t, side="right") - 1, 0, len(waypoint_time) - 2)
    f = (t - waypoint_time[k]) / (waypoint_time[k + 1] - waypoint_time[k])
    return waypoint_drones[k] + f[:, None, None] * (waypoint_drones[k + 1] - waypoint_drones[k])


def planned_configurations(track: Track, t: NDArray) -> NDArray[np.float64]:
    """Planned configurations at times t, linear between dense samples (angles unwrapped)."""
    from flycrane.planning.interpolation import interpolate

    k, f = track.index_at(t)
    return interpolate(track.q[k], track.q[k + 1], f)


def check_flight(
    system: CableSystem,
    track: Track,
    drones: NDArray[np.float64],
    times: NDArray[np.float64],
    validity: SafetyCheck,
) -> LegCheck:
    """Reconstruct the load under given drone positions (C, 3, 3) at times (C,) and measure."""
    planned = planned_configurations(track, times)
    rebuilt = configuration_from_drone_positions(system, drones, initial=planned)
    b = platform_points_from_configuration(system, planned)
    cable = np.abs(np.linalg.norm(drones[:, CABLE_DRONE] - b, axis=-1) - system.cable_lengths).max(
        axis=1
    )
    return LegCheck(
        valid=rebuilt.converged & validity(rebuilt.q),
        platform_deviation=np.linalg.norm(rebuilt.q[:, :3] - planned[:, :3], axis=1),
        cable_length_error=cable,
        times=times,
        q=rebuilt.q,
    )


def reduce_to_waypoints(
    system: CableSystem, track: Track, validity: SafetyCheck, options: MissionOptions
) -> WaypointPlan:
    """Fewest waypoints (greedy recursive splitting) whose legs pass every check."""
    last = len(track.time) - 1
    pending = [(0, last)]
    accepted: dict[int, tuple[int, LegCheck]] = {}
    failure = ""
    while pending:
        i, j = pending.pop()
        t0, t1 = track.time[i], track.time[j]
        count = max(2, int(np.ceil((t1 - t0) / options.check_resolution)) + 1)
        times = np.linspace(t0, t1, count)
        ends = np.stack([track.drones[i], track.drones[j]])
        check = check_flight(
            system, track, drone_positions_at(np.array([t0, t1]), ends, times), times, validity
        )
        badness = check.badness(options)
        if badness.max() <= 1.0 and t1 - t0 <= options.max_leg_duration:
            accepted[i] = (j, check)
            continue
        if j - i <= 1:
            failure = (
                f"no safe straight leg between {t0:.2f} s and {t1:.2f} s of the track "
                f"(worst check at {times[int(np.argmax(badness))]:.2f} s)"
            )
            accepted[i] = (j, check)
            continue
        if t1 - t0 > options.max_leg_duration and badness.max() <= 1.0:
            split = (i + j) // 2
        else:
            worst = times[int(np.argmax(badness))]
            split = int(np.clip(np.searchsorted(track.time, worst), i + 1, j - 1))
        pending += [(split, j), (i, split)]
    chain = [0]
    while chain[-1] != last:
        chain.append(accepted[chain[-1]][0])
    checks = [accepted[i][1] for i in chain[:-1]]
    indices = np.array(chain)
    return WaypointPlan(
        ok=not failure,
        indices=indices,
        time=track.time[indices],
        q=track.q[indices],
        drones=track.drones[indices],
        max_platform_deviation=float(max(c.platform_deviation.max() for c in checks)),
        max_cable_length_error=float(max(c.cable_length_error.max() for c in checks)),
        reason=failure,
    )


def stored_positions(enu: NDArray[np.float64], options: MissionOptions) -> NDArray[np.float64]:
    """ENU positions (..., 3) as ArduPilot flies them: latitude and longitude rounded to
    1e-7 degree (about 1 cm), altitudes truncated to whole centimetres. Speeds planned for
    unrounded positions would be off by the rounding: on a leg that moves centimetres in one
    direction, by tens of percent in that direction's limit."""
    origin = options.origin
    lat, lon, amsl = geodetic_from_enu(enu, origin)
    stored = ardupilot_altitude(options.item_altitude(np.asarray(enu, dtype=float)[..., 2], amsl))
    return enu_from_geodetic(
        degrees_to_int(lat) * DEGREE_UNIT,
        degrees_to_int(lon) * DEGREE_UNIT,
        options.item_amsl(stored),
        origin,
    )


@dataclass(frozen=True)
class StoredWaypoints:
    """Waypoints at dense samples ``indices``, plus the set-down's goal if there is one."""

    indices: NDArray[np.int64]
    q: NDArray[np.float64]  #: (W, 9)
    drones: NDArray[np.float64]  #: (W, 3, 3) as stored
    planned: NDArray[np.float64]  #: (W,) planned times [s]


def stored_waypoints(
    system: CableSystem,
    track: Track,
    indices: NDArray[np.int64],
    options: MissionOptions,
    set_down: VerticalLeg | None,
) -> StoredWaypoints:
    """The waypoints at dense samples ``indices`` (and the set-down's goal after them), with
    the drones where the autopilots will store them (:func:`stored_positions`)."""
    q, planned = track.q[indices], track.time[indices]
    if set_down is not None:
        q = np.concatenate([q, set_down.low[None]])
        planned = np.append(planned, planned[-1] + set_down.height / options.vertical_leg_speed)
    drones = stored_positions(drone_positions_from_configuration(system, q), options)
    return StoredWaypoints(indices, q, drones, planned)
