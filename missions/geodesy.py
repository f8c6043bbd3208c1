"""Local ENU to WGS84 (pymap3d), and the rounding MAVLink's integer coordinates need.

MISSION_ITEM_INT carries latitude and longitude as integers of 1e-7 degree (about 1.1 cm).
We round half away from zero, never truncate: truncation biases every coordinate towards
the equator and the prime meridian, by up to 1.1 cm, differently for each drone. The
altitude travels as a float32 [m]; ArduPilot keeps it in whole centimetres, truncated
(:func:`ardupilot_altitude`), so a mission writes the middle of the centimetre it means
(:func:`mission_altitude`).
"""

from __future__ import annotations

import numpy as np
import pymap3d
from numpy.typing import ArrayLike, NDArray

from missions.options import GeodeticOrigin

#: Degrees per unit of a MAVLink integer coordinate.
DEGREE_UNIT = 1e-7


def geodetic_from_enu(
    enu: ArrayLike, origin: GeodeticOrigin
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """(latitude [deg], longitude [deg], altitude AMSL [m]) of ENU points (..., 3)."""
    enu = np.asarray(enu, dtype=float)
    lat, lon, alt = pymap3d.enu2geodetic(
        enu[..., 0], enu[..., 1], enu[..., 2], origin.latitude, origin.longitude, origin.altitude
    )
    return np.asarray(lat), np.asarray(lon), np.asarray(alt)


def enu_from_geodetic(
    latitude: ArrayLike, longitude: ArrayLike, altitude: ArrayLike, origin: GeodeticOrigin
) -> NDArray[np.float64]:
    """ENU points (..., 3) of geodetic coordinates (degrees, metres AMSL)."""
    e, n, u = pymap3d.geodetic2enu(
        latitude, longitude, altitude, origin.latitude, origin.longitude, origin.altitude
    )
    return np.stack([np.asarray(e), np.asarray(n), np.asarray(u)], axis=-1)


def degrees_to_int(degrees: ArrayLike) -> NDArray[np.int64]:
    """Degrees as 1e-7 degree integers, rounded half away from zero."""
    # Snap to 1e-6 units first: 47.39775 deg is 473977499.99999994 units in binary floating
    # point, and must round up like the decimal it stands for.
    scaled = np.round(np.asarray(degrees, dtype=float) / DEGREE_UNIT, 6)
    return (np.sign(scaled) * np.floor(np.abs(scaled) + 0.5)).astype(np.int64)


def ardupilot_altitude(z: ArrayLike) -> NDArray[np.float64]:
    """Altitude [m] ArduPilot flies for a MISSION_ITEM_INT ``z`` [m].

    AP_Mission stores ``packet.z * 100.0f`` in an integer of centimetres (Location::alt):
    the float32 product, truncated towards zero. So 2.026 m is flown as 2.02 m.
    """
    product = np.asarray(z, dtype=np.float32) * np.float32(100.0)
    return np.trunc(product).astype(np.float64) / 100.0


def mission_altitude(altitude: ArrayLike) -> NDArray[np.float64]:
    """The item ``z`` [m] that ArduPilot stores as the whole centimetre nearest
    ``altitude``: the middle of that centimetre.

    Writing the centimetre itself is not enough: ``n / 100`` is often just below it in
    float32 (0.29 is 0.28999999) or in the float64 of a planned position after the ENU
    round trip, and :func:`ardupilot_altitude` truncates both to the centimetre below,
    which changes a short climb's length and so its timing (BENCHMARKS.md, "Flights on
    three ArduCopter SITL autopilots"). Half a centimetre is far beyond float32's
    resolution below 80 km.
    """
    centimetres = np.round(np.asarray(altitude, dtype=float) * 100.0)
    return (centimetres + np.copysign(0.5, centimetres)) / 100.0


def ned_from_enu(enu: ArrayLike) -> NDArray[np.float64]:
    """Vectors or positions (..., 3) from east, north, up to north, east, down axes."""
    enu = np.asarray(enu, dtype=float)
    return np.stack([enu[..., 1], enu[..., 0], -enu[..., 2]], axis=-1)


def enu_from_ned(ned: ArrayLike) -> NDArray[np.float64]:
    """Inverse of :func:`ned_from_enu`."""
    ned = np.asarray(ned, dtype=float)
    return np.stack([ned[..., 1], ned[..., 0], -ned[..., 2]], axis=-1)
