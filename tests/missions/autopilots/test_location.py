"""ArduPilot's metres against the task's: a task-frame offset is as many of ArduPilot's
metres as the scale says, by ArduPilot's own distance formula on pymap3d's coordinates."""

from __future__ import annotations

import numpy as np
import pytest

from missions.autopilots.location import local_scale
from missions.geodesy import geodetic_from_enu
from missions.options import GeodeticOrigin
from tests.missions.helpers import ardupilot_distance_ne


@pytest.mark.parametrize("latitude", [0.0, 47.3977, -33.9, 70.0])
def test_a_task_offset_is_as_many_ardupilot_metres_as_the_scale_says(latitude):
    """7 m east and 5 m north of the origin, within 0.02 mm (the scale is the first-order
    term; the mean latitude's cosine and the plane's curvature are below that here)."""
    origin = GeodeticOrigin(latitude=latitude, longitude=8.5, altitude=400.0)
    lat, lon, _ = geodetic_from_enu(np.array([7.0, 5.0, 0.0]), origin)
    north, east = ardupilot_distance_ne((latitude, 8.5), lat, lon)
    k_north, k_east = local_scale(latitude, 400.0)
    assert north == pytest.approx(5.0 * k_north, abs=2e-5)
    assert east == pytest.approx(7.0 * k_east, abs=2e-5)


def test_ardupilot_reads_north_long_and_east_short_by_tenths_of_a_percent():
    """At the default origin (47.4 deg, 488 m) north 0.12 % long and east 0.19 % short: 5 m
    are 6 and 9 mm off; at the equator north 0.67 % long (a sphere of about the equatorial
    radius against the meridian's a (1 - e^2))."""
    k_north, k_east = local_scale(47.3977, 488.0)
    assert 1.0011 < k_north < 1.0012
    assert 0.9981 < k_east < 0.9982
    assert local_scale(0.0, 0.0)[0] == pytest.approx(1.0067, abs=1e-4)
