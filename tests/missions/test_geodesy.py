"""Geodesy: MAVLink integer degrees round half away from zero; ENU <-> WGS84 against the radii
of curvature of the WGS84 ellipsoid and a round trip."""

from __future__ import annotations

from decimal import ROUND_HALF_UP, Decimal

import numpy as np
import pytest

from missions.geodesy import (
    ardupilot_altitude,
    degrees_to_int,
    enu_from_geodetic,
    geodetic_from_enu,
    mission_altitude,
)
from missions.options import GeodeticOrigin
from tests.missions.helpers import WGS84_A, WGS84_E2


@pytest.mark.parametrize(
    ("degrees", "units"),
    [
        (47.12345675, 471234568),  # exactly half a unit: away from zero...
        (-47.12345675, -471234568),  # ...on both sides
        (8.54560945, 85456095),
        (-122.08399995, -1220840000),
        (0.00000005, 1),
        (-0.00000005, -1),
        (179.99999995, 1800000000),
        (-179.99999995, -1800000000),
        (47.39775, 473977500),  # 473977499.99999994 in binary: must not drop a unit
        (47.12345674, 471234567),  # below half: down (truncation would agree)...
        (47.12345676, 471234568),  # ...above half: up (truncation would not)
        (-47.12345679, -471234568),
        (0.0, 0),
    ],
)
def test_degrees_round_to_the_nearest_unit_half_away_from_zero(degrees, units):
    assert int(degrees_to_int(degrees)) == units


def test_degrees_to_int_agrees_with_decimal_rounding_on_many_values():
    rng = np.random.default_rng(7)
    # decimals with 8 to 10 places; about one in thirty ends exactly on a half unit
    values = np.array(
        [
            round(v, int(d))
            for v, d in zip(rng.uniform(-180, 180, 4000), rng.integers(8, 11, 4000), strict=True)
        ]
    )
    got = degrees_to_int(values)
    assert got.dtype == np.int64 and got.shape == values.shape
    expected = [
        int((Decimal(repr(float(v))) * 10**7).quantize(Decimal(1), rounding=ROUND_HALF_UP))
        for v in values
    ]
    np.testing.assert_array_equal(got, expected)


def radii(latitude_deg):
    """WGS84 meridian (M) and prime-vertical (N) radii of curvature [m]."""
    s2 = np.sin(np.radians(latitude_deg)) ** 2
    return WGS84_A * (1 - WGS84_E2) / (1 - WGS84_E2 * s2) ** 1.5, WGS84_A / np.sqrt(
        1 - WGS84_E2 * s2
    )


ORIGINS = [
    GeodeticOrigin(),
    GeodeticOrigin(latitude=0.0, longitude=0.0, altitude=0.0),
    GeodeticOrigin(latitude=-62.5, longitude=-58.9, altitude=30.0),
    GeodeticOrigin(latitude=27.98, longitude=86.92, altitude=5300.0),
]


@pytest.mark.parametrize("origin", ORIGINS, ids=lambda o: f"{o.latitude}")
@pytest.mark.parametrize("metres", [1.0, 10.0])
def test_a_metre_north_east_and_up_matches_the_radii_of_curvature(origin, metres):
    meridian, normal = radii(origin.latitude)
    lat, lon, alt = geodetic_from_enu(np.array([[0, metres, 0], [metres, 0, 0], [0, 0, metres]]),
                                      origin)  # fmt: skip
    north = np.radians(lat[0] - origin.latitude) * (meridian + origin.altitude)
    east = (
        np.radians(lon[1] - origin.longitude)
        * (normal + origin.altitude)
        * np.cos(np.radians(origin.latitude))
    )
    assert north == pytest.approx(metres, abs=1e-3)
    assert east == pytest.approx(metres, abs=1e-3)
    assert alt[2] - origin.altitude == pytest.approx(metres, abs=1e-6)
    # the textbook figure: about 1 / 111,111 degree of latitude per metre
    assert (lat[0] - origin.latitude) / metres == pytest.approx(1 / 111_111, rel=0.006)


@pytest.mark.parametrize("origin", ORIGINS, ids=lambda o: f"{o.latitude}")
def test_enu_to_geodetic_and_back_is_the_identity(origin):
    rng = np.random.default_rng(3)
    enu = rng.uniform([-5000, -5000, -100], [5000, 5000, 1000], (500, 3))
    lat, lon, alt = geodetic_from_enu(enu, origin)
    np.testing.assert_allclose(enu_from_geodetic(lat, lon, alt, origin), enu, atol=1e-6)
    # the origin itself
    lat0, lon0, alt0 = geodetic_from_enu(np.zeros(3), origin)
    assert (float(lat0), float(lon0)) == pytest.approx((origin.latitude, origin.longitude))
    assert float(alt0) == pytest.approx(origin.altitude, abs=1e-6)


def test_every_centimetre_written_as_mission_altitude_is_stored_as_itself():
    """Brute force over every centimetre from -1 km to 9 km (AMSL altitudes of real
    places): ArduPilot's ``int32(float32(z) * 100.0f)`` gives back the centimetre, also from
    a value a hair below it (the ENU round trip of a stored position)."""
    centimetres = np.arange(-100_000, 900_001)
    for wobble in (0.0, -1e-7, 1e-7):
        z = mission_altitude(centimetres / 100.0 + wobble)
        stored = (z.astype(np.float32) * np.float32(100.0)).astype(np.int32)
        assert np.array_equal(stored, centimetres)
    assert float(ardupilot_altitude(mission_altitude(6.7499995))) == 6.75
