"""What an onboard player needs: each drone's trajectory as the player's binary file, and
its mission with the player's item.

The mission is the drone's own (:mod:`missions.export.builder`) up to its hold at the start,
then NAV_SCRIPT_TIME (the player, :mod:`missions.execution.onboard`, plays the trajectory
from the group clock), then the mission's own last item (the hold, or the landing, at the
end). The file is the one ``missions/execution/lua/flycrane_player.lua`` reads: little
endian, a 24-byte header ``"FCT1"``, uint32 rows, float32 step [s], int32 home latitude and
longitude [1e-7 deg], float32 home altitude AMSL [m], then per row 10 float32: plan time,
north, east, down [m] from home, velocity [m/s], acceleration [m/s^2]. North and east are
ArduPilot's metres (:mod:`missions.autopilots.location`) from the home as the header rounds
it, which is where ArduPilot places the home the player adds them to.
"""

from __future__ import annotations

import struct

import numpy as np
from numpy.typing import NDArray

from missions.autopilots.location import VehicleFrame
from missions.export.items import DroneMission, MavCmd, MavFrame, MissionItem
from missions.geodesy import DEGREE_UNIT, degrees_to_int, geodetic_from_enu
from missions.options import GeodeticOrigin

#: NAV_SCRIPT_TIME's command (param1) that selects the player.
PLAYER_COMMAND = 1
#: Its timeout (param2, a byte on ArduPilot: at most 255 s); 0: none, the player ends it.
PLAYER_TIMEOUT = 0
HEADER = struct.Struct("<4sIfiif")


def player_file(
    time: NDArray[np.float64],
    position: NDArray[np.float64],
    velocity: NDArray[np.float64],
    acceleration: NDArray[np.float64],
    home: NDArray[np.float64],
    origin: GeodeticOrigin,
) -> bytes:
    """One drone's file (module docstring): ``time`` (N,), uniform; home-relative ENU
    ``position``, ``velocity``, ``acceleration`` (N, 3); ``home`` (3,), ENU in the task
    frame about ``origin``."""
    step = float(time[1] - time[0])
    lat, lon, alt = (float(c) for c in geodetic_from_enu(home, origin))
    lat_int, lon_int = int(degrees_to_int(lat)), int(degrees_to_int(lon))
    header = HEADER.pack(b"FCT1", len(time), step, lat_int, lon_int, alt)
    # the vehicle's frame about the home as the header rounds it, heights from the home
    frame = VehicleFrame.at(lat_int * DEGREE_UNIT, lon_int * DEGREE_UNIT, origin, 0.0, home[2])
    rows = np.column_stack(
        [
            time,
            frame.local_position(home + position),
            frame.local_vector(velocity),
            frame.local_vector(acceleration),
        ]
    ).astype("<f4")
    return header + rows.tobytes()


def onboard_mission(mission: DroneMission, hold_seq: int) -> DroneMission:
    """The drone's mission with the player in place of its legs (module docstring)."""
    player = MissionItem(
        seq=0,
        frame=MavFrame.MISSION,
        command=MavCmd.NAV_SCRIPT_TIME,
        param1=float(PLAYER_COMMAND),
        param2=float(PLAYER_TIMEOUT),
    )
    items = [*mission.items[: hold_seq + 1], player, mission.items[-1]]
    return DroneMission(mission.drone, tuple(it.with_seq(s) for s, it in enumerate(items)))
