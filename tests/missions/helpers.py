"""Helpers shared by the mission tests, written independently of the modules under test:
a first-order WGS84 conversion, ArduCopter's leg-timing rule, and hand-made plans."""

from __future__ import annotations

import numpy as np

from flycrane.cable_system import CableSystem
from flycrane.kinematics import drone_positions_from_configuration
from missions.items import MavCmd
from missions.options import GeodeticOrigin
from missions.waypoints import WaypointPlan

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


def encoded_leg_vectors(mission, origin: GeodeticOrigin):
    """ENU displacements (L, 3) of the timed legs as an ArduPilot copter stores them:
    coordinates of 1e-7 degree, altitudes truncated to whole centimetres (AP_Mission keeps
    ``int32(z * 100)``); inverse of :func:`approximate_geodetic`."""
    items = [mission.items[2], *nav_waypoints(mission)]
    lat = np.array([i.x for i in items]) * 1e-7
    lon = np.array([i.y for i in items]) * 1e-7
    z = np.trunc(np.array([i.z for i in items]) * 100.0) / 100.0
    lat0 = np.radians(origin.latitude)
    w = 1 - WGS84_E2 * np.sin(lat0) ** 2
    meridian = WGS84_A * (1 - WGS84_E2) / w**1.5
    normal = WGS84_A / np.sqrt(w)
    north = np.radians(lat - origin.latitude) * (meridian + origin.altitude)
    east = np.radians(lon - origin.longitude) * (normal + origin.altitude) * np.cos(lat0)
    return np.diff(np.stack([east, north, z], axis=1), axis=0)


def nav_waypoints(mission):
    """The timed NAV_WAYPOINTs: after home (seq 0), takeoff (1) and the start (2)."""
    return [it for it in mission.items[3:] if it.command == MavCmd.NAV_WAYPOINT]


def flown_leg_durations(mission, leg_vectors):
    """Leg durations under ArduCopter's speed rule, from the mission's items in order.

    ``leg_vectors`` (L, 3) are the drone's ENU displacements of the L timed legs.
    """
    limits = {1: None, 2: None, 3: None}  # ground, climb, descent [m/s]
    durations = []
    for item in mission.items[3:]:
        if item.command == MavCmd.DO_CHANGE_SPEED:
            assert item.param3 == -1.0  # throttle unchanged
            limits[int(item.param1)] = item.param2
        elif item.command == MavCmd.NAV_WAYPOINT:
            delta = leg_vectors[len(durations)]
            length = np.linalg.norm(delta)
            horizontal, vertical = np.linalg.norm(delta[:2]) / length, abs(delta[2]) / length
            candidates = []
            if horizontal > 0:
                candidates.append(limits[1] / horizontal)
            if vertical > 0:
                candidates.append(limits[2 if delta[2] > 0 else 3] / vertical)
            durations.append(length / min(candidates))
    return np.array(durations)


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
