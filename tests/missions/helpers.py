"""Helpers shared by the mission tests, written independently of the modules under test:
a first-order WGS84 conversion, ArduPilot's own, and hand-made plans."""

from __future__ import annotations

import numpy as np

from flycrane.model.cable_system import CableSystem
from flycrane.model.kinematics import drone_positions_from_configuration
from missions.autopilots.ardupilot import ArduCopterSettings
from missions.autopilots.spline import SpeedLimits
from missions.export.builder import RELEASE_SEQ
from missions.export.items import MavCmd
from missions.options import GeodeticOrigin
from missions.trajectory.flight_plan import FlightPlan
from missions.trajectory.motion import DroneMotion
from missions.trajectory.waypoints import WaypointPlan

WGS84_A, WGS84_F = 6378137.0, 1 / 298.257223563
WGS84_E2 = WGS84_F * (2 - WGS84_F)


def approximate_geodetic(enu, origin: GeodeticOrigin):
    """(lat, lon) [deg] of ENU points near the origin: north / (M + h), east / ((N + h) cos).

    Second-order terms are below 1e-5 m within 10 m of the origin, far below 1e-7 degree.
    """
    enu = np.asarray(enu, dtype=float)
    lat0 = np.radians(origin.latitude)
    w = 1 - WGS84_E2 * np.sin(lat0) ** 2
    meridian = WGS84_A * (1 - WGS84_E2) / w**1.5
    normal = WGS84_A / np.sqrt(w)
    lat = origin.latitude + np.degrees(enu[..., 1] / (meridian + origin.altitude))
    lon = origin.longitude + np.degrees(enu[..., 0] / ((normal + origin.altitude) * np.cos(lat0)))
    return lat, lon


def ardupilot_distance_ne(origin: tuple[float, float], lat, lon):
    """(north, east) [m] from ``origin`` (lat, lon [deg]) to points [deg] as ArduPilot's
    ``Location::get_distance_NE`` computes them (AP_Common/Location.cpp, 4.5): 1e-7 degree
    units times LOCATION_SCALING_FACTOR, longitude times the cosine of the mean latitude."""
    factor = 0.011131884502145034
    lat0, lon0 = origin
    north = (np.asarray(lat) - lat0) * 1e7 * factor
    mean = np.radians((np.asarray(lat) + lat0) / 2)
    return north, (np.asarray(lon) - lon0) * 1e7 * factor * np.cos(mean)


def hand_made_plan(displacements, durations, start=(0.0, 0.0, 5.0)):
    """A WaypointPlan of a rigidly translated crane (hover attitude) through P offsets."""
    p = np.cumsum(np.vstack([start, displacements]), axis=0)
    q = np.tile([0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0, 1.0, 1.0], (len(p), 1))
    q[:, :3] = p
    time = np.concatenate([[0.0], np.cumsum(durations)])
    return WaypointPlan(
        ok=True, indices=np.arange(len(p)), time=time, q=q,
        drones=drone_positions_from_configuration(CableSystem.from_spec(), q),
        max_platform_deviation=0.0, max_cable_length_error=0.0,
    )  # fmt: skip


def hand_made_flight(displacements, limits, start=(0.0, 0.0, 5.0)):
    """A FlightPlan of a rigidly translated crane (hover attitude) through P offsets, each
    leg with the given SpeedLimits on every drone; times and motion are placeholders (the
    mission builder reads the waypoints and limits only)."""
    straight = hand_made_plan(displacements, [1.0] * len(displacements), start)
    return FlightPlan(
        ok=True, reason="", indices=straight.indices, time=straight.time, q=straight.q,
        drones=straight.drones, limits=(tuple(limits),) * 3,
        motion=DroneMotion.straight(straight.time, straight.drones),
        vehicles=DroneMotion.straight(straight.time, straight.drones),
        settings=ArduCopterSettings(), early=(), max_platform_deviation=0.0,
        max_cable_length_error=0.0, max_tracking_deviation=0.0, track_time=straight.time,
    )  # fmt: skip


def applied_limits(mission, initial: SpeedLimits) -> list[SpeedLimits]:
    """The limits in force when each spline leg starts, as ArduCopter applies the items
    (design.md section 9): DO_CHANGE_SPEED type 1 ground, 2 climb, 3 descent; a ground speed
    below 0.2 m/s is ignored; items run from the release on."""
    limits = {1: initial.horizontal, 2: initial.up, 3: initial.down}
    legs = []
    for item in mission.items[RELEASE_SEQ:]:
        if item.command == MavCmd.DO_CHANGE_SPEED:
            assert item.param3 == -1.0  # throttle unchanged
            kind, value = int(item.param1), item.param2
            if value > 0 and not (kind == 1 and value < 0.2):
                limits[kind] = value
        elif item.command == MavCmd.NAV_SPLINE_WAYPOINT:
            legs.append(SpeedLimits(limits[1], limits[2], limits[3]))
    return legs
