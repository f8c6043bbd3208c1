"""A recorded flight read back from telemetry logs: one ``.tlog`` per drone.

Any tlog works: ours (SITL flights, :mod:`missions.sitl.harness`) or a ground station's from
a real flight. Per drone this reads

- the autopilot's estimate: LOCAL_POSITION_NED placed by GPS_GLOBAL_ORIGIN and
  HOME_POSITION in the vehicle's own metres (:class:`~missions.autopilots.location.
  VehicleFrame`, as the executors place their targets), timed by its own ``time_boot_ms``;
  where a log lacks them, GLOBAL_POSITION_INT, whose whole 1e-7 degrees (ArduPilot
  truncates its offsets from the EKF origin) are up to 1.1 cm off;
- the truth where a simulator reports it: SIM_STATE (``lat_int``/``lon_int``, altitude AMSL);
- the mission's progress: MISSION_CURRENT changes and MISSION_ITEM_REACHED.

SIM_STATE and the mission messages have no time field. Each takes the midpoint of the
vehicle times of the timed messages just before and just after it in the log: the vehicle
sends a stream's messages of one instant together, in an order of its own (ArduCopter
4.5.7 sends SIM_STATE before and MISSION_CURRENT after GLOBAL_POSITION_INT), so the
midpoint is within half a stream period (10 ms at the 50 Hz our harness asks for) whatever
that order is;
- the log's own record times (the ground's receipt clock, common to the drones of one
  ground station), kept beside each vehicle time to align the drones
  (:mod:`missions.flight_report.alignment`).
"""

from __future__ import annotations

import struct
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray
from pymavlink import mavutil

from flycrane.errors import FieldProblem, InputError
from flycrane.user_files import regular_file
from missions.autopilots.location import VehicleFrame
from missions.geodesy import DEGREE_UNIT, enu_from_geodetic
from missions.options import GeodeticOrigin

#: What pymavlink's parser raises on bytes that are not MAVLink where it expects them.
PARSE_ERRORS = (AttributeError, IndexError, KeyError, TypeError, ValueError, struct.error)
#: Messages that carry the vehicle's own time.
TIMED = frozenset({"GLOBAL_POSITION_INT", "SYSTEM_TIME", "ATTITUDE", "LOCAL_POSITION_NED"})


@dataclass(frozen=True)
class PositionSeries:
    """Positions in the task's ENU frame on the vehicle's clock."""

    time: NDArray[np.float64]  #: (N,) vehicle time [s]
    enu: NDArray[np.float64]  #: (N, 3) [m]
    log_time: NDArray[np.float64]  #: (N,) the log record's time [s]

    def at(self, t: NDArray[np.float64]) -> NDArray[np.float64]:
        """Positions at vehicle times ``t`` (linear between samples) (len(t), 3)."""
        return np.column_stack([np.interp(t, self.time, self.enu[:, i]) for i in range(3)])


@dataclass(frozen=True)
class SeqEvents:
    """Mission items by vehicle time: (time [s], log time [s], seq) rows."""

    time: NDArray[np.float64]
    log_time: NDArray[np.float64]
    seq: NDArray[np.int64]

    def first(self, seq: int) -> tuple[float, float] | None:
        """(vehicle time, log time) of the first event of ``seq``."""
        hits = np.flatnonzero(self.seq == seq)
        return (float(self.time[hits[0]]), float(self.log_time[hits[0]])) if len(hits) else None


@dataclass(frozen=True)
class VehicleLog:
    """What one drone's log says (module docstring)."""

    name: str
    system_id: int
    estimated: PositionSeries
    true: PositionSeries | None  #: None without SIM_STATE (a real vehicle)
    current: SeqEvents  #: MISSION_CURRENT changes
    reached: SeqEvents  #: MISSION_ITEM_REACHED
    #: common time minus vehicle time [s] (SYSTEM_TIME's UNIX time against its boot time:
    #: GPS time on a real vehicle, the simulators' shared epoch on SITL); None without it
    clock_offset: float | None = None


def _timed(rows: Sequence[Sequence[float]], columns: int) -> NDArray[np.float64]:
    array = np.array(rows, dtype=float).reshape(-1, columns)
    return array[np.isfinite(array[:, 0])]


def _events(rows: Sequence[Sequence[float]]) -> SeqEvents:
    array = _timed(rows, 3)
    return SeqEvents(array[:, 0], array[:, 1], array[:, 2].astype(np.int64))


def _track(rows: Sequence[Sequence[float]], origin: GeodeticOrigin) -> PositionSeries:
    array = _timed(rows, 5)
    enu = enu_from_geodetic(
        array[:, 2] * DEGREE_UNIT, array[:, 3] * DEGREE_UNIT, array[:, 4], origin
    )
    return PositionSeries(array[:, 0], enu, array[:, 1])


def _local_track(
    rows: Sequence[Sequence[float]],
    ekf_origin: tuple[int, int, int] | None,
    home_down: float | None,
    origin: GeodeticOrigin,
    home_height: float | None,
) -> PositionSeries | None:
    """The estimate from LOCAL_POSITION_NED rows (time, log time, north, east, down), or
    None without them or the frame that places them."""
    if not rows or ekf_origin is None or (home_height is not None and home_down is None):
        return None
    lat, lon, alt = ekf_origin[0] * DEGREE_UNIT, ekf_origin[1] * DEGREE_UNIT, ekf_origin[2] / 1000
    if home_height is None:  # heights from the EKF origin's altitude
        home_down, home_up = 0.0, alt - origin.altitude
    else:
        home_up = home_height
    assert home_down is not None
    frame = VehicleFrame.at(lat, lon, origin, home_down, home_up)
    array = _timed(rows, 5)
    return PositionSeries(array[:, 0], frame.task_position(array[:, 2:]), array[:, 1])


def _unreadable(name: str, path: Path, error: Exception) -> InputError:
    return InputError(
        [FieldProblem(name, f"{path} is not a readable tlog: {type(error).__name__}: {error}")]
    )


def read_vehicle_log(
    path: Path, name: str, origin: GeodeticOrigin, home_height: float | None = None
) -> VehicleLog:
    """Read one drone's tlog (module docstring); positions in ENU about ``origin``. With
    ``home_height``, the estimate's height is the vehicle's own above its home (relative
    altitude), home standing that high above the ground, as the plan's altitudes count
    (:class:`~missions.options.MissionOptions`); else its estimated AMSL altitude.

    Raises
    ------
    InputError
        If the file is not a readable tlog, or has no GLOBAL_POSITION_INT with a position.
    """
    # mavutil takes a path that names no file for a serial device, and reads a device or
    # a FIFO without end: only a regular file is a log
    try:
        regular_file(Path(path), name)
    except InputError as error:
        raise error.about(path) from None
    try:
        log = mavutil.mavlink_connection(str(path), dialect="ardupilotmega", robust_parsing=True)
    except OSError as error:
        raise InputError([FieldProblem(name, f"cannot read {path}: {error}")]) from None
    except PARSE_ERRORS as error:
        raise _unreadable(name, path, error) from None
    estimated: list[tuple[float, float, int, int, float]] = []
    local: list[tuple[float, float, float, float, float]] = []
    ekf_origin: tuple[int, int, int] | None = None
    home_down: float | None = None
    true: list[list[float]] = []
    current: list[list[float]] = []
    reached: list[list[float]] = []
    waiting: list[list[float]] = []  # untimed rows whose time is the next midpoint
    offsets: list[float] = []
    boot: float | None = None
    system_id = 0
    try:
        while (msg := log.recv_msg()) is not None:
            kind, stamp = msg.get_type(), float(getattr(msg, "_timestamp", 0.0))
            if kind in TIMED:
                now = msg.time_boot_ms / 1000.0
                for row in waiting:
                    row[0] = now if boot is None else (boot + now) / 2.0
                waiting.clear()
                boot = now
            if kind == "SYSTEM_TIME" and msg.time_unix_usec > 0:
                offsets.append(msg.time_unix_usec / 1e6 - msg.time_boot_ms / 1000.0)
            if kind == "GLOBAL_POSITION_INT" and (msg.lat or msg.lon):
                system_id = msg.get_srcSystem()
                altitude = msg.alt / 1000.0
                if home_height is not None:
                    altitude = origin.altitude + home_height + msg.relative_alt / 1000.0
                estimated.append((now, stamp, msg.lat, msg.lon, altitude))
            elif kind == "LOCAL_POSITION_NED":
                local.append((now, stamp, msg.x, msg.y, msg.z))
            elif kind == "GPS_GLOBAL_ORIGIN":
                ekf_origin = (msg.latitude, msg.longitude, msg.altitude)
            elif kind == "HOME_POSITION":
                home_down = float(msg.z)
            elif kind == "SIM_STATE":
                lat = getattr(msg, "lat_int", 0) or round(msg.lat / DEGREE_UNIT)
                lon = getattr(msg, "lon_int", 0) or round(msg.lon / DEGREE_UNIT)
                true.append([np.nan, stamp, lat, lon, float(msg.alt)])
                waiting.append(true[-1])
            elif kind == "MISSION_CURRENT" and (not current or current[-1][2] != msg.seq):
                current.append([np.nan, stamp, msg.seq])
                waiting.append(current[-1])
            elif kind == "MISSION_ITEM_REACHED":
                reached.append([np.nan, stamp, msg.seq])
                waiting.append(reached[-1])
    except PARSE_ERRORS as error:
        raise _unreadable(name, path, error) from None
    finally:
        log.close()
    # rows after the last timed message have no time: dropped by the finite filters
    if not estimated:
        raise InputError([FieldProblem(name, f"{path} has no GLOBAL_POSITION_INT position")])
    return VehicleLog(
        name=name,
        system_id=system_id,
        estimated=_local_track(local, ekf_origin, home_down, origin, home_height)
        or _track(estimated, origin),
        true=_track(true, origin) if true else None,
        current=_events(current),
        reached=_events(reached),
        clock_offset=float(np.median(offsets)) if offsets else None,
    )
