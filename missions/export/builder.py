"""Per-drone MAVLink missions of a flight plan (``missions.autopilots.ardupilot`` says what
ArduCopter does with each item, ``docs/missions.md`` how to fly them).

Every drone's mission has the same structure and the same timed waypoints:

====  ========================  ============================================================
seq   command                   meaning
====  ========================  ============================================================
0     NAV_WAYPOINT (home)       ArduPilot's home slot: the ground (z = 0) below the drone's
                                start, altitude AMSL; overwritten at arming with the real
                                home, where the drone stands: ``home_height`` above the
                                ground, which relative altitudes count from
1     NAV_TAKEOFF               climb vertically to the start altitude
2     NAV_LOITER_UNLIM          **hold at the start until released**: the ground station
                                sends MISSION_SET_CURRENT with seq 3 to all three drones
                                back to back once all three hover there
...   DO_CHANGE_SPEED           before a leg, each speed limit that differs from the previous
                                leg's: ground (param1 1), climb (2), descent (3) [m/s]; the
                                limit the leg's timing rests on, the others generous
...   NAV_SPLINE_WAYPOINT       the next timed waypoint, flown without stopping; with a
                                set-down the last one is the goal on its surface
last  NAV_LOITER_UNLIM          hold at the last waypoint (NAV_LAND if ``end = "land"``)
====  ========================  ============================================================

The item after the last spline waypoint is not a spline and is at the same place, so every
drone brakes to rest there (ArduPilot's spline leg then ends with a zero tangent). A start
that lies within the clearance of a surface is reached by the take-off itself, which lifts
the load (``missions.trajectory.vertical_legs``).

No NAV_DELAY stands next to a spline waypoint (ArduCopter's rule,
:mod:`missions.autopilots.ardupilot`, "Around a spline leg").
"""

from __future__ import annotations

import numpy as np

from missions.autopilots.ardupilot import changed_limits
from missions.autopilots.spline import SpeedLimits
from missions.export.items import DroneMission, MavCmd, MavFrame, MissionItem
from missions.geodesy import degrees_to_int, geodetic_from_enu, mission_altitude
from missions.options import MissionOptions
from missions.trajectory.flight_plan import FlightPlan

#: DO_CHANGE_SPEED speed types (param1) of each limit.
SPEED_TYPE = {"horizontal": 1, "up": 2, "down": 3}


def _position_item(
    command: MavCmd, lat: float, lon: float, z: float, frame: MavFrame
) -> MissionItem:
    return MissionItem(
        seq=0,
        frame=frame,
        command=command,
        x=int(degrees_to_int(lat)),
        y=int(degrees_to_int(lon)),
        z=float(z),
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


def speed_items(previous: SpeedLimits, limits: SpeedLimits) -> list[MissionItem]:
    """DO_CHANGE_SPEED items for every limit of ``limits`` that differs from ``previous``,
    in the order ArduCopter's model expects them (:func:`changed_limits`)."""
    return [_speed_item(SPEED_TYPE[name], getattr(limits, name))
            for name in changed_limits(previous, limits)]  # fmt: skip


def build_missions(plan: FlightPlan, options: MissionOptions) -> list[DroneMission]:
    """One mission per drone (module docstring)."""
    origin = options.origin
    relative = options.altitude_frame == "relative"
    frame = MavFrame.GLOBAL_RELATIVE_ALT_INT if relative else MavFrame.GLOBAL_INT
    lat, lon, amsl = geodetic_from_enu(plan.drones, origin)  # (K, 3) each
    height = mission_altitude(options.item_altitude(plan.drones[..., 2], amsl))
    start = plan.drones[0]
    ground = np.concatenate([start[:, :2], np.zeros((3, 1))], axis=1)
    home_lat, home_lon, home_amsl = geodetic_from_enu(ground, origin)
    missions = []
    for j in range(3):
        items = [
            _position_item(
                MavCmd.NAV_WAYPOINT, home_lat[j], home_lon[j], home_amsl[j], MavFrame.GLOBAL_INT
            ),
            _position_item(MavCmd.NAV_TAKEOFF, lat[0, j], lon[0, j], height[0, j], frame),
            _position_item(MavCmd.NAV_LOITER_UNLIM, lat[0, j], lon[0, j], height[0, j], frame),
        ]
        previous = plan.settings.initial_speeds
        for k, limits in enumerate(plan.limits[j]):
            items += speed_items(previous, limits)
            previous = limits
            items.append(
                _position_item(
                    MavCmd.NAV_SPLINE_WAYPOINT,
                    lat[k + 1, j],
                    lon[k + 1, j],
                    height[k + 1, j],
                    frame,
                )
            )
        end = MavCmd.NAV_LOITER_UNLIM if options.end == "hold" else MavCmd.NAV_LAND
        items.append(_position_item(end, lat[-1, j], lon[-1, j], height[-1, j], frame))
        missions.append(
            DroneMission(drone=j + 1, items=tuple(it.with_seq(s) for s, it in enumerate(items)))
        )
    return missions


#: The hold every drone waits in until the release (seq).
HOLD_SEQ = 2
#: The item the release jumps to: the first leg's speed items, or its waypoint.
RELEASE_SEQ = HOLD_SEQ + 1
