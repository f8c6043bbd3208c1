"""Spline waypoint legs (NAV_SPLINE_WAYPOINT) for the mock autopilot, as ArduCopter 4.5
flies them.

Nothing of the flight itself is re-derived here: the leg's curve, its speed law and the
vehicle's lag are :mod:`missions.autopilots.spline`'s, the single model of what ArduPilot
does. This module does what the vehicle does around a leg when a spline waypoint starts,
by the rules stated there ("Geometry") and in :mod:`missions.autopilots.ardupilot`
("Around a spline leg", "Speeds"):

- **Tangents**: the origin tangent carried from the previous spline leg (zero from rest),
  the destination tangent from the next nav item (:func:`destination_tangent`).
- **Exit speed bound**: the next leg's entry limit (SplineCurve's origin speed max) computed
  now, with the limits in force now; 0 when the vehicle stops at the waypoint.
- The leg is flown by :func:`~missions.autopilots.spline.fly_leg` from the speed and the
  vehicle state the previous leg ended with, and **played back** in simulated time: the
  target's position at any instant is interpolated between the 400 Hz samples.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from missions.autopilots.ardupilot import ArduCopterSettings
from missions.autopilots.spline import (
    HermiteLeg,
    LegFlight,
    SpeedLimits,
    entry_speed_limit,
    fly_leg,
    vehicle_state,
)


@dataclass(frozen=True)
class NextWaypoint:
    """The nav item after a waypoint: where it is [ENU m] and whether it is a spline."""

    position: NDArray[np.float64]
    spline: bool


def destination_tangent(
    origin: NDArray[np.float64], destination: NDArray[np.float64], following: NextWaypoint | None
) -> NDArray[np.float64]:
    """The tangent a leg from ``origin`` to ``destination`` ends with
    (:mod:`missions.autopilots.spline`, "Geometry"); zero for a stop (``following`` None)."""
    if following is None:
        return np.zeros(3)
    return following.position - (origin if following.spline else destination)


@dataclass(frozen=True)
class SplineLeg:
    """One spline leg as flown, to be played back."""

    curve: HermiteLeg
    flown: LegFlight

    @property
    def duration(self) -> float:
        return self.flown.duration

    @property
    def exit_speed(self) -> float:
        return self.flown.exit_speed

    def at(self, t: float) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """The target's position and velocity [ENU m, m/s] ``t`` [s] after the leg's start
        (held at the end)."""
        u = float(np.interp(t, self.flown.time, self.flown.u))
        speed = float(np.interp(t, self.flown.time, self.flown.speed))
        tangent = self.curve.derivatives(u)[0]
        norm = float(np.linalg.norm(tangent))
        direction = tangent / norm if norm > 0.0 else np.zeros(3)
        return self.curve.position(u), direction * speed

    def vehicle_at(self, t: float) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """The modelled vehicle's position and velocity ``t`` [s] after the leg's start
        (held at the end): it lags the target as the position controller lets it."""
        time, vehicle = self.flown.time, self.flown.vehicle
        position = np.array([np.interp(t, time, vehicle[:, i]) for i in range(3)])
        k = int(np.clip(np.searchsorted(time, t), 1, len(time) - 1))
        velocity = (vehicle[k] - vehicle[k - 1]) / max(time[k] - time[k - 1], 1e-9)
        return position, velocity


class SplineNavigator:
    """What one vehicle carries from one spline leg into the next (module docstring)."""

    def __init__(self, settings: ArduCopterSettings) -> None:
        self.settings = settings
        self.stop()

    def stop(self) -> None:
        """The next spline leg starts from rest."""
        self._tangent: NDArray[np.float64] | None = None
        self._entry = 0.0
        self._state: NDArray[np.float64] | None = None

    def leg(
        self,
        origin: NDArray[np.float64],
        destination: NDArray[np.float64],
        following: NextWaypoint | None,
        after: NextWaypoint | None,
        limits: SpeedLimits,
        setup: SpeedLimits,
    ) -> SplineLeg:
        """Set up the leg from ``origin`` to ``destination`` with the limits ``setup`` and
        fly it with ``limits``; ``following`` is the nav item after it (None: a stop) and
        ``after`` the one after that."""
        accel = self.settings.accel_limits
        start = np.zeros(3) if self._tangent is None else self._tangent
        end = destination_tangent(origin, destination, following)
        curve = HermiteLeg.between(origin, destination, start, end)
        exit_max = 0.0
        if following is not None and following.spline and np.any(end):
            ahead = destination_tangent(destination, following.position, after)
            exit_max = entry_speed_limit(
                HermiteLeg.between(destination, following.position, end, ahead), setup, accel
            )
        state = vehicle_state(origin) if self._state is None else self._state
        flown = fly_leg(curve, limits, accel, self._entry, exit_max, self.settings.tracking, state)
        if exit_max > 0.0:
            self._tangent, self._entry, self._state = end, flown.exit_speed, flown.state
        else:
            self.stop()
        return SplineLeg(curve, flown)
