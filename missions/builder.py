"""Per-drone MAVLink missions from timed waypoints (docs/missions.md says what autopilots do).

Every drone's mission has the same structure and the same number of timed waypoints:

====  =======================  ==============================================================
seq   command                  meaning
====  =======================  ==============================================================
0     NAV_WAYPOINT (home)      ArduPilot's home slot: the point on the ground (z = 0) below
                               the drone's start position, altitude AMSL. Overwritten at
                               arming with the real home; PX4 ignores it as a home.
1     NAV_TAKEOFF              climb vertically to the start altitude
2     NAV_WAYPOINT             the start position, hold ``start_hold`` s (integer seconds)
(3)   NAV_DELAY                optional barrier: wait until ``start_time_utc`` (hh:mm:ss)
...   DO_CHANGE_SPEED          before a leg whose speeds differ from the previous leg's:
                               ground speed (type 1) = horizontal leg length / duration, and
                               climb (type 2) or descent (type 3) speed = vertical / duration,
                               so that ArduCopter's track speed limit makes the leg last its
                               planned duration
...   NAV_WAYPOINT             the next timed waypoint (pass through, acceptance radius)
last  NAV_LOITER_UNLIM         hold at the end (or NAV_LAND if ``end = "land"``)
====  =======================  ==============================================================

All three missions are started together by one MISSION_START (see ``missions.mavlink``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from missions.geodesy import (
    DEGREE_UNIT,
    ardupilot_altitude,
    degrees_to_int,
    enu_from_geodetic,
    geodetic_from_enu,
)
from missions.items import DroneMission, MavCmd, MavFrame, MissionItem
from missions.options import MissionOptions
from missions.waypoints import WaypointPlan

#: Speed changes smaller than this fraction of the new speed are not worth a DO_CHANGE_SPEED
#: item (a leg of 10 s takes at most 10 ms longer or shorter). Relative, not absolute: the
#: vertical components of near-level legs are millimetres per second, and an absolute 1 mm/s
#: kept from the previous leg made such a leg last up to 60 % longer (the climb limit binds).
SPEED_TOLERANCE = 0.001
#: ArduCopter ignores horizontal speeds below WPNAV_WP_SPEED_MIN (AC_WPNav set_speed_NE):
#: 20 cm/s up to Copter 4.5 (ArduPilot PR #5508), 10 cm/s after PR #27952 (August 2024),
#: 1 cm/s in later masters. Such legs keep the previous limit (flagged in the summary): a
#: leg that also climbs or descends still gets its duration from the vertical limit.
ARDUCOPTER_MIN_GROUND_SPEED = 0.20
#: DO_CHANGE_SPEED speed types (param1).
GROUND_SPEED, CLIMB_SPEED, DESCENT_SPEED = 1, 2, 3


@dataclass(frozen=True)
class LegSpeeds:
    """Per drone and leg: horizontal and vertical speed components [m/s], (L, 3) each."""

    horizontal: NDArray[np.float64]
    vertical: NDArray[np.float64]  #: signed: > 0 climbing

    @classmethod
    def of(cls, plan: WaypointPlan) -> LegSpeeds:
        return cls.between(plan.time, plan.drones)

    @classmethod
    def between(cls, time: NDArray[np.float64], drones: NDArray[np.float64]) -> LegSpeeds:
        """Speeds of drones (K, 3, 3) [m] flying straight legs between times (K,) [s]."""
        delta = np.diff(drones, axis=0)  # (L, 3 drones, 3)
        duration = np.diff(time)[:, None]
        return cls(np.linalg.norm(delta[..., :2], axis=-1) / duration, delta[..., 2] / duration)

    def slow_legs(self) -> list[tuple[int, int]]:
        """(drone, leg) pairs, 1-based, that ArduCopter may fly faster than planned: level
        legs whose ground speed is below its minimum (module constants)."""
        level = np.abs(self.vertical) <= 1e-6
        slow = level & (self.horizontal > 1e-6) & (self.horizontal < ARDUCOPTER_MIN_GROUND_SPEED)
        return [(int(j) + 1, int(k) + 1) for k, j in zip(*np.nonzero(slow), strict=True)]


def _position_item(
    command: MavCmd,
    lat: float,
    lon: float,
    z: float,
    frame: MavFrame,
    param1: float = 0.0,
    param2: float = 0.0,
) -> MissionItem:
    return MissionItem(
        seq=0,
        frame=frame,
        command=command,
        x=int(degrees_to_int(lat)),
        y=int(degrees_to_int(lon)),
        z=float(z),
        param1=param1,
        param2=param2,
    )


def _speed_item(speed_type: int, speed: float) -> MissionItem:
    return MissionItem(
        seq=0,
        frame=MavFrame.MISSION,
        command=MavCmd.DO_CHANGE_SPEED,
        param1=float(speed_type),
        param2=float(speed),
        param3=-1.0,
    )


def build_missions(plan: WaypointPlan, options: MissionOptions) -> list[DroneMission]:
    """One mission per drone (module docstring), all with the same timed waypoints."""
    origin = options.origin
    relative = options.altitude_frame == "relative"
    frame = MavFrame.GLOBAL_RELATIVE_ALT_INT if relative else MavFrame.GLOBAL_INT
    lat, lon, amsl = geodetic_from_enu(plan.drones, origin)  # (K, 3) each
    height = plan.drones[..., 2] if relative else amsl
    home_lat, home_lon, home_amsl = geodetic_from_enu(
        np.concatenate([plan.drones[0, :, :2], np.zeros((3, 1))], axis=1), origin
    )
    # Speeds of the legs as the autopilot gets them: latitude and longitude rounded to 1e-7
    # degree (~1 cm), altitudes truncated to whole centimetres (ArduPilot). The ground and
    # vertical limits are both exact for a leg, so a limit computed from unrounded positions
    # slows the leg down whenever rounding lengthens that part: near-vertical legs move only
    # centimetres sideways and level ones centimetres up. On the Rescue plan rounding made a
    # lift leg 5 % slower (0.26 s) and truncation would add up to 25 % to level legs (drone
    # 1 would end 1 s late, seven times the plan's timing tolerance).
    stored = ardupilot_altitude(height)
    encoded = enu_from_geodetic(degrees_to_int(lat) * DEGREE_UNIT,
                                degrees_to_int(lon) * DEGREE_UNIT,
                                stored + origin.altitude if relative else stored,
                                origin)  # fmt: skip
    speeds = LegSpeeds.between(plan.time, encoded)
    missions = []
    for j in range(3):
        items = [
            _position_item(
                MavCmd.NAV_WAYPOINT, home_lat[j], home_lon[j], home_amsl[j], MavFrame.GLOBAL_INT
            ),
            _position_item(MavCmd.NAV_TAKEOFF, lat[0, j], lon[0, j], height[0, j], frame),
            _position_item(
                MavCmd.NAV_WAYPOINT,
                lat[0, j],
                lon[0, j],
                height[0, j],
                frame,
                param1=float(options.start_hold),
                param2=options.acceptance_radius,
            ),
        ]
        if options.start_time_utc is not None:
            at = options.start_time_utc
            items.append(
                MissionItem(
                    seq=0,
                    frame=MavFrame.MISSION,
                    command=MavCmd.NAV_DELAY,
                    param1=-1.0,
                    param2=float(at.hour),
                    param3=float(at.minute),
                    param4=float(at.second),
                )
            )
        ground = climb = descent = None
        for k in range(len(plan.time) - 1):
            h, v = float(speeds.horizontal[k, j]), float(speeds.vertical[k, j])
            if h > 1e-6 and (ground is None or abs(h - ground) > SPEED_TOLERANCE * h):
                items.append(_speed_item(GROUND_SPEED, h))
                ground = h
            if v > 1e-6 and (climb is None or abs(v - climb) > SPEED_TOLERANCE * v):
                items.append(_speed_item(CLIMB_SPEED, v))
                climb = v
            elif v < -1e-6 and (descent is None or abs(-v - descent) > SPEED_TOLERANCE * -v):
                items.append(_speed_item(DESCENT_SPEED, -v))
                descent = -v
            items.append(
                _position_item(
                    MavCmd.NAV_WAYPOINT,
                    lat[k + 1, j],
                    lon[k + 1, j],
                    height[k + 1, j],
                    frame,
                    param2=options.acceptance_radius,
                )
            )
        end = MavCmd.NAV_LOITER_UNLIM if options.end == "hold" else MavCmd.NAV_LAND
        items.append(_position_item(end, lat[-1, j], lon[-1, j], height[-1, j], frame))
        missions.append(
            DroneMission(drone=j + 1, items=tuple(it.with_seq(s) for s, it in enumerate(items)))
        )
    return missions
