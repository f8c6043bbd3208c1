"""A drone's estimate read back from its tlog: LOCAL_POSITION_NED placed by its EKF origin
and home in ArduPilot's own metres (a log written here, the local position by ArduPilot's
distance formula on a first-order WGS84 conversion), and GLOBAL_POSITION_INT where a log
has nothing else."""

from __future__ import annotations

import struct
from pathlib import Path

import numpy as np
import pytest
from pymavlink.dialects.v20 import ardupilotmega

from flycrane.errors import InputError
from missions.flight_report.vehicle_log import read_vehicle_log
from missions.options import GeodeticOrigin
from tests.missions.helpers import approximate_geodetic, ardupilot_distance_ne

ORIGIN = GeodeticOrigin()
HOME_HEIGHT = 2.0
#: where the drone is, in the task frame: 6 m east, 5 m north, 4 m up of the origin
POINT = np.array([6.0, 5.0, 4.0])


def _log(path: Path, local: bool) -> None:
    """One drone at POINT for 1 s at 10 Hz, its EKF origin (and home, 0.3 m above it)
    about 1 m west and 2 m south of the task's origin; LOCAL_POSITION_NED with ``local``,
    always GLOBAL_POSITION_INT as ArduPilot sends it (its offset truncated to 1e-7 deg)."""
    mav = ardupilotmega.MAVLink(None, srcSystem=1)
    lat0, lon0 = (round(float(c) * 1e7) for c in approximate_geodetic([-1.0, -2.0, 0.0], ORIGIN))
    lat, lon = (float(c) for c in approximate_geodetic(POINT, ORIGIN))
    north, east = ardupilot_distance_ne((lat0 * 1e-7, lon0 * 1e-7), lat, lon)
    home_down = -0.3
    down = home_down - (POINT[2] - HOME_HEIGHT)
    with path.open("wb") as log:

        def write(message, boot_ms: int) -> None:
            log.write(struct.pack(">Q", int((1.8e9 + boot_ms / 1000) * 1e6)))
            log.write(message.pack(mav))

        write(mav.gps_global_origin_encode(lat0, lon0, 488_000, 0), 0)
        write(mav.home_position_encode(lat0, lon0, 488_300, 0, 0, home_down, [1, 0, 0, 0],
                                       0, 0, 0, 0), 0)  # fmt: skip
        # ArduPilot's Location::offset truncates the offset from the origin
        lat_int, lon_int = lat0 + int(lat * 1e7 - lat0), lon0 + int(lon * 1e7 - lon0)
        relative = round((home_down - down) * 1000)  # above home [mm]
        for i in range(10):
            ms = 1000 + 100 * i
            write(mav.global_position_int_encode(ms, lat_int, lon_int, 0, relative, 0, 0, 0, 0), ms)
            if local:
                write(mav.local_position_ned_encode(ms, north, east, down, 0, 0, 0), ms)


def test_the_estimate_is_the_local_position_in_the_vehicle_s_metres(tmp_path):
    """Within 0.1 mm of the point (float32 metres), where GLOBAL_POSITION_INT's truncated
    degrees would be up to 1.1 cm off."""
    _log(tmp_path / "d.tlog", local=True)
    estimated = read_vehicle_log(tmp_path / "d.tlog", "d", ORIGIN, HOME_HEIGHT).estimated
    assert len(estimated.time) == 10
    np.testing.assert_allclose(estimated.enu, np.tile(POINT, (10, 1)), atol=1e-4)


def test_a_log_without_the_local_position_is_read_from_its_global_position(tmp_path):
    _log(tmp_path / "d.tlog", local=False)
    estimated = read_vehicle_log(tmp_path / "d.tlog", "d", ORIGIN, HOME_HEIGHT).estimated
    assert len(estimated.time) == 10
    error = estimated.enu - POINT
    assert np.abs(error[:, :2]).max() <= 0.012
    assert error[:, 2] == pytest.approx(np.zeros(10), abs=1e-3)


@pytest.mark.parametrize(
    ("name", "reason"),
    [("d1.tlog", "No such file"), (".", "not a regular file"), ("/dev/zero", "not a regular file")],
)
def test_only_a_regular_file_is_read_as_a_log(tmp_path, monkeypatch, name, reason):
    """mavutil would open a path that names no file as a serial port, and read a device
    without end."""
    monkeypatch.chdir(tmp_path)
    with pytest.raises(InputError, match=rf"drone1: {name}: {reason}"):
        read_vehicle_log(Path(name), "drone1", ORIGIN, HOME_HEIGHT)


def test_bytes_the_mavlink_parser_chokes_on_are_named(tmp_path):
    """18 bytes of a SITL tlog whose every 97th byte was replaced (a new user's corrupt
    file): pymavlink raises AttributeError while it opens them, which went out as a
    traceback."""
    path = tmp_path / "drone1.tlog"
    path.write_bytes(bytes.fromhex("000661733f3c9296fd190000170101160000"))
    with pytest.raises(InputError, match=f"drone1: {path} is not a readable tlog"):
        read_vehicle_log(path, "drone1", ORIGIN)
