"""A drone's chain of spline legs as ArduCopter flies it: released from rest at the first
point, one set of speed limits per leg (the DO_CHANGE_SPEED items before it), stopping at
the last point (the final hold).

Each leg is set up when it starts, with the limits in force then: the previous leg's with
only the first of this leg's DO items applied (ArduCopter's rule,
:func:`~missions.autopilots.ardupilot.limits_at_setup`); the speed at which it may end is
the next leg's entry limit computed with those limits, and the next leg starts at the speed
the previous one ended with (:mod:`missions.autopilots.spline`).

Both the target and the modelled vehicle are kept: the vehicle is where the drone will be
(nearer the flown positions than the target: BENCHMARKS.md, "Moved from code comments"), so
plans are checked and flights judged against it.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from missions.autopilots.ardupilot import limits_at_setup
from missions.autopilots.spline import (
    WPNAV_DT,
    AccelLimits,
    HermiteLeg,
    SpeedLimits,
    Tracking,
    entry_speed_limit,
    fly_leg,
    legs_through,
    vehicle_state,
)

#: How long a vehicle takes to settle onto its last waypoint after the target arrived [s]:
#: a few time constants of the position controller (1 / PSC_POSXY_P = 1 s).
SETTLE_S = 2.0


@dataclass(frozen=True)
class ChainFlight:
    """Where the target is, every step, and when each waypoint is reached."""

    legs: tuple[HermiteLeg, ...]
    arrival: NDArray[np.float64]  #: (K,) [s]: 0 at the release, then each waypoint
    time: NDArray[np.float64]  #: (N,) every step [s]
    position: NDArray[np.float64]  #: (N, 3) the target [m]
    speed: NDArray[np.float64]  #: (N,) the target's [m/s]
    vehicle: NDArray[np.float64]  #: (N, 3) the modelled vehicle following it [m]

    def at(self, t: NDArray[np.float64]) -> NDArray[np.float64]:
        """Target positions at times ``t`` (held at the ends), (len(t), 3)."""
        return _interpolate(t, self.time, self.position)

    def vehicle_at(self, t: NDArray[np.float64]) -> NDArray[np.float64]:
        """Modelled vehicle positions at times ``t`` (len(t), 3): the vehicle settles onto
        the last waypoint within :data:`SETTLE_S` of the last arrival, and stays there."""
        time = np.append(self.time, self.time[-1] + SETTLE_S)
        return _interpolate(t, time, np.vstack([self.vehicle, self.position[-1:]]))


def _interpolate(
    t: NDArray[np.float64], time: NDArray[np.float64], values: NDArray[np.float64]
) -> NDArray[np.float64]:
    t = np.asarray(t, dtype=float)
    return np.column_stack([np.interp(t, time, values[:, i]) for i in range(3)])


def fly_chain(
    points: NDArray[np.float64],
    limits: Sequence[SpeedLimits],
    accel: AccelLimits,
    initial: SpeedLimits | None = None,
    tracking: Tracking | None = None,
    dt: float = WPNAV_DT,
) -> ChainFlight:
    """Fly the spline chain through ``points`` (K, 3) with ``limits[k]`` on leg k after the
    ``initial`` limits (WPNAV_SPEED*; default: the first leg's, all in force when it is set
    up), the vehicle following its target as ``tracking`` says."""
    legs = legs_through(points)
    if len(limits) != len(legs):
        raise ValueError(f"{len(limits)} speed limits for {len(legs)} legs")
    times, positions, speeds, arrival = [np.zeros(1)], [points[:1]], [np.zeros(1)], [0.0]
    vehicle = [points[:1]]
    entry, start, previous = 0.0, 0.0, limits[0] if initial is None else initial
    state = vehicle_state(points[0])
    for k, (leg, limit) in enumerate(zip(legs, limits, strict=True)):
        setup, previous = limits_at_setup(previous, limit), limit
        exit_max = entry_speed_limit(legs[k + 1], setup, accel) if k + 1 < len(legs) else 0.0
        flown = fly_leg(leg, limit, accel, entry, exit_max, tracking, state, dt)
        state = flown.state
        times.append(start + flown.time[1:])
        positions.append(leg.position(flown.u[1:]))
        vehicle.append(flown.vehicle[1:])
        speeds.append(flown.speed[1:])
        start += flown.duration
        arrival.append(start)
        entry = flown.exit_speed
    return ChainFlight(
        tuple(legs),
        np.array(arrival),
        np.concatenate(times),
        np.concatenate(positions),
        np.concatenate(speeds),
        np.concatenate(vehicle),
    )
