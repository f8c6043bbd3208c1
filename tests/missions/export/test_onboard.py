"""The onboard player's file as the Lua player reads it: a row's north and east, added to
the header's home as ArduPilot's Location measures from it, land on the planned point
(ArduPilot's own distance formula on a first-order WGS84 conversion)."""

from __future__ import annotations

import struct

import numpy as np
import pytest

from missions.export.onboard import HEADER, player_file
from missions.options import GeodeticOrigin
from tests.missions.helpers import approximate_geodetic, ardupilot_distance_ne


def test_a_row_on_the_header_s_home_lands_on_the_planned_point():
    """Home 3 m east, 2 m south and 2 m up of the origin; the drone 6 m east, 4 m north and
    1.5 m up of it, moving 0.5 m/s east: north and east from the home as the header rounds
    it (1e-7 degree) in ArduPilot's metres, within 0.01 mm; the velocity their rate."""
    origin = GeodeticOrigin()
    home = np.array([3.0, -2.0, 2.0])
    position = np.array([[0.0, 0.0, 0.0], [6.0, 4.0, 1.5]])
    velocity = np.array([[0.0, 0.0, 0.0], [0.5, 0.0, -0.1]])
    data = player_file(np.array([0.0, 0.1]), position, velocity, np.zeros((2, 3)), home, origin)
    magic, n, step, lat, lon, _ = HEADER.unpack_from(data)
    assert (magic, n, step) == (b"FCT1", 2, pytest.approx(0.1))
    assert len(data) == HEADER.size + n * struct.calcsize("<10f")
    rows = np.frombuffer(data, "<f4", offset=HEADER.size).reshape(n, 10).astype(float)
    header_home = (lat * 1e-7, lon * 1e-7)
    for k in range(n):
        point = approximate_geodetic(home + position[k], origin)
        assert rows[k, 1:3] == pytest.approx(ardupilot_distance_ne(header_home, *point), abs=1e-5)
    assert rows[1, 3] == pytest.approx(-1.5)
    ahead = approximate_geodetic(home + position[1] + velocity[1], origin)
    rate = np.subtract(ardupilot_distance_ne(header_home, *ahead), rows[1, 1:3])
    assert rows[1, 4:7] == pytest.approx([*rate, 0.1], abs=1e-5)
