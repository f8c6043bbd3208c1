"""ArduPilot's local metres against the task's: how its ``Location`` measures north and east.

ArduPilot measures north and east from a point (the EKF origin, a home) on a sphere of
6378.1 km (``Location::get_distance_NE`` and ``Location::offset``: LOCATION_SCALING_FACTOR
metres per 1e-7 degree of latitude, times the cosine of the mean latitude for longitude),
and its EKF turns every GNSS fix into its local NED frame so. Our task frame is WGS84's
tangent plane (:mod:`missions.geodesy`), whose radii of curvature differ from that sphere's
by 0.1-0.2 % at mid latitudes (at 47 deg the meridian's is 0.13 % shorter, the prime
vertical's 0.18 % longer). A target given in a vehicle's local frame must be in the vehicle's
metres: the same numbers as task metres put a drone 5 m from its EKF origin about a
centimetre from the point meant (3 cm near the equator, where the meridian's radius is
0.67 % shorter), each drone by its own offset, and the formation with it. Over the tens of
metres a task spans the ratio is constant to a few parts in 10^7, so a scale per axis is
the whole conversion (:func:`local_scale`), and :class:`VehicleFrame` places a vehicle's
local frame in the task's.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from missions.geodesy import enu_from_geodetic
from missions.options import GeodeticOrigin

#: ArduPilot's metres per 1e-7 degree of latitude (AP_Common/Location.h).
LOCATION_SCALING_FACTOR = 0.011131884502145034
#: The radius [m] of the sphere that factor implies.
SPHERE_RADIUS = LOCATION_SCALING_FACTOR * 1e7 * 180.0 / math.pi
#: WGS84: semi-major axis [m] and first eccentricity squared.
WGS84_A = 6378137.0
WGS84_E2 = 6.69437999014e-3


def local_scale(latitude: float, altitude: float) -> tuple[float, float]:
    """ArduPilot's local metres per metre of WGS84's tangent plane at ``latitude`` [deg] and
    ``altitude`` [m] (north, east): the sphere's radius over the ellipsoid's radii of
    curvature there, the meridian's and the prime vertical's, each raised by the altitude
    (ArduPilot's sphere has one radius at every height)."""
    w = 1.0 - WGS84_E2 * math.sin(math.radians(latitude)) ** 2
    meridian = WGS84_A * (1.0 - WGS84_E2) / w**1.5
    prime_vertical = WGS84_A / math.sqrt(w)
    return SPHERE_RADIUS / (meridian + altitude), SPHERE_RADIUS / (prime_vertical + altitude)


@dataclass(frozen=True)
class VehicleFrame:
    """Where a vehicle's local NED frame lies in the task's ENU frame: its EKF origin
    (horizontally), its metres per task metre north and east (:func:`local_scale` at the
    origin) and its home's local down coordinate."""

    origin_east: float  #: [m] in the task's ENU frame
    origin_north: float
    scale: tuple[float, float]  #: the vehicle's metres per task metre, (north, east)
    home_down: float  #: HOME_POSITION z: home's down coordinate in the local frame [m]
    home_up: float  #: the home's height in the task frame (``home_height``) [m]

    @classmethod
    def at(
        cls,
        latitude: float,
        longitude: float,
        origin: GeodeticOrigin,
        home_down: float,
        home_up: float,
    ) -> VehicleFrame:
        """The frame of a vehicle whose EKF origin is at ``latitude``, ``longitude`` [deg]
        (GPS_GLOBAL_ORIGIN), in the task frame about ``origin``."""
        east, north, _ = enu_from_geodetic(latitude, longitude, origin.altitude, origin)
        scale = local_scale(latitude, origin.altitude)
        return cls(float(east), float(north), scale, home_down, home_up)

    def local_position(self, enu: NDArray[np.float64]) -> NDArray[np.float64]:
        """Task-frame ENU positions (..., 3) in the vehicle's local NED frame."""
        enu = np.asarray(enu, dtype=float)
        north = (enu[..., 1] - self.origin_north) * self.scale[0]
        east = (enu[..., 0] - self.origin_east) * self.scale[1]
        down = self.home_down - (enu[..., 2] - self.home_up)
        return np.stack([north, east, down], axis=-1)

    def task_position(self, ned: NDArray[np.float64]) -> NDArray[np.float64]:
        """Inverse of :meth:`local_position`."""
        ned = np.asarray(ned, dtype=float)
        east = ned[..., 1] / self.scale[1] + self.origin_east
        north = ned[..., 0] / self.scale[0] + self.origin_north
        up = self.home_down - ned[..., 2] + self.home_up
        return np.stack([east, north, up], axis=-1)

    def local_vector(self, enu: NDArray[np.float64]) -> NDArray[np.float64]:
        """Task-frame ENU velocities or accelerations of a target (..., 3) in local NED: the
        rates of its local position (the EKF's own velocity is in true metres)."""
        enu = np.asarray(enu, dtype=float)
        north, east = enu[..., 1] * self.scale[0], enu[..., 0] * self.scale[1]
        return np.stack([north, east, -enu[..., 2]], axis=-1)
