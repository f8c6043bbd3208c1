"""Waypoint times and per-drone speed limits with which ArduCopter flies three spline chains
in step.

Leg by leg from the release, with the model of :mod:`missions.autopilots.spline`:

1. **The leg's time.** Each drone's shortest duration (its binding limit at the drone speed
   limit) and longest (at the lowest limit ArduCopter accepts, see below) bracket what it
   can fly. The leg ends at the planned time (the dense plan's time law, shifted by any
   delay so far), raised to the slowest drone's shortest and, where possible, lowered to
   the fastest drone's longest.
2. **Each drone's limit.** One limit binds: the horizontal speed on legs that are mostly
   horizontal, else the climb or descent speed; the others keep the generous defaults. It
   is found by bisection on the leg's flown duration (which falls as the limit rises), the
   target being the leg's end time minus the drone's *modelled* arrival at its start, so an
   error on one leg is taken back on the next instead of adding up.

A horizontal limit cannot be set below ArduCopter's ground-speed floor
(:data:`~missions.autopilots.ardupilot.MIN_GROUND_SPEED`). A mostly horizontal leg that
must be slower is timed by its climb or descent limit instead, if it climbs or descends at
all (by a stored centimetre), with its horizontal limit held at the floor rather than
generous: where the spline levels off and the vertical limit lets go, the floor still
bounds the speed. A level leg that should be slower is flown at the floor and reported as
early (:attr:`FleetSpeeds.early`), and the flight plan merges it with a neighbour where it
can (:mod:`missions.trajectory.flight_plan`).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import NDArray

from missions.autopilots.ardupilot import MIN_GROUND_SPEED, ArduCopterSettings, limits_at_setup
from missions.autopilots.chain import ChainFlight, fly_chain
from missions.autopilots.spline import (
    MAX_LEG_TIME,
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

#: Bisection steps on the binding limit (its bracket shrinks by 2^-40).
BISECTION_STEPS = 40
#: Highest speed limit searched [m/s].
MAX_LIMIT = 5.0
#: Lowest climb or descent limit searched [m/s].
MIN_VERTICAL = 1e-3
#: A leg may be timed by its vertical limit alone (horizontal generous) if it climbs or
#: descends at least this much and at least this share of its length: on a nearly level
#: spline the vertical limit binds only where the curve slopes [m, -].
MIN_VERTICAL_EXTENT = 0.05
MIN_VERTICAL_SHARE = 0.3
#: Less than this and a leg counts as level: altitudes are stored in whole centimetres [m].
LEVEL = 0.01


@dataclass(frozen=True)
class FleetSpeeds:
    """The waypoint times and, per drone, the limits of every leg and the modelled flight."""

    times: NDArray[np.float64]  #: (K,) waypoint times [s from the release]
    limits: tuple[tuple[SpeedLimits, ...], ...]  #: [drone][leg]
    flights: tuple[ChainFlight, ...]  #: per drone
    early: tuple[tuple[int, int], ...]  #: (drone, leg), 1-based: flown faster than planned
    late: tuple[tuple[int, int], ...]  #: (drone, leg): slower than planned


@dataclass(frozen=True)
class LegOutcome:
    """What the solver reads of a leg flight (:class:`~missions.autopilots.spline.LegFlight`)."""

    duration: float  #: [s]
    exit_speed: float  #: the target's speed at the leg's end [m/s]
    state: NDArray[np.float64]  #: the vehicle at the leg's end (shared: never modified)


class LegFlights:
    """Outcomes of leg flights by their exact inputs, for the timings of one flight plan.
    The plan times one set of waypoints after another (a leg split, a waypoint dropped), and
    every leg before the change is set up exactly as before, so the search's trial flights
    there repeat, most of a later timing's (BENCHMARKS.md, "``flycrane plan`` end to end",
    "Second round"). Only the outcomes are kept: the trajectories would cost memory in
    proportion to every trial flight."""

    def __init__(self) -> None:
        self._known: dict[tuple, LegOutcome] = {}

    def fly(
        self,
        leg: HermiteLeg,
        speed: SpeedLimits,
        accel: AccelLimits,
        entry_speed: float,
        exit_speed_max: float,
        tracking: Tracking,
        state: NDArray[np.float64],
        max_time: float,
    ) -> LegOutcome:
        """:func:`~missions.autopilots.spline.fly_leg`, flown once per distinct input."""
        key = (
            leg.coefficients.tobytes(), speed, accel, entry_speed, exit_speed_max, tracking,
            state.tobytes(), max_time,
        )  # fmt: skip
        outcome = self._known.get(key)
        if outcome is None:
            flight = fly_leg(
                leg, speed, accel, entry_speed, exit_speed_max, tracking, state,
                max_time=max_time,
            )  # fmt: skip
            outcome = LegOutcome(flight.duration, flight.exit_speed, flight.state)
            self._known[key] = outcome
        return outcome


@dataclass
class _Drone:
    legs: list[HermiteLeg]
    state: NDArray[np.float64]  # the vehicle at the start of the next leg (vehicle_state)
    limits: SpeedLimits  # those of the previous leg (the WPNAV_SPEED* before the first)
    entry: float = 0.0  # target speed at the start of the next leg [m/s]
    start: float = 0.0  # modelled time of the start of the next leg [s]


def _axis(chord: NDArray[np.float64]) -> str:
    horizontal = float(np.hypot(chord[0], chord[1]))
    if horizontal >= abs(chord[2]):
        return "horizontal"
    return "up" if chord[2] > 0 else "down"


def _limit(generous: SpeedLimits, axis: str, value: float) -> SpeedLimits:
    """The limits with ``axis`` at ``value``: "horizontal", "up", "down", or "up/floor",
    "down/floor" (the vertical limit binding, the horizontal one at ArduCopter's floor)."""
    if axis.endswith("/floor"):
        return replace(generous, horizontal=MIN_GROUND_SPEED, **{axis.split("/")[0]: value})
    return replace(generous, **{axis: value})


class _LegProblem:
    """One drone's next leg: flown duration and exit speed for a binding limit value."""

    def __init__(
        self, drone: _Drone, k: int, settings: ArduCopterSettings, flights: LegFlights
    ) -> None:
        self.drone, self.k, self.settings, self.flights = drone, k, settings, flights
        leg = drone.legs[k]
        self.chord = leg.destination - leg.origin
        self.axis = _axis(self.chord)

    @property
    def climbs(self) -> bool:
        """Whether the leg climbs or descends by at least a stored centimetre."""
        return abs(float(self.chord[2])) >= LEVEL

    def _vertical(self) -> str:
        return "up" if self.chord[2] > 0 else "down"

    def fly(self, axis: str, value: float, against: float | None = None) -> LegOutcome:
        """The leg flown with the binding ``axis`` at ``value``; with ``against`` [s], only
        until it is sure to last longer than that (its duration is then some value above
        ``against``): shorter or longer is all the search asks, and the slow limits it tries
        fly for minutes (1 mm/s climbs). Two steps of margin keep a stopped flight's
        duration above ``against`` in floating point."""
        legs, k = self.drone.legs, self.k
        limit = _limit(self.settings.initial_speeds, axis, value)
        accel = self.settings.accel_limits
        setup = limits_at_setup(self.drone.limits, limit)
        exit_max = entry_speed_limit(legs[k + 1], setup, accel) if k + 1 < len(legs) else 0.0
        max_time = MAX_LEG_TIME
        if against is not None:
            max_time = min(max_time, max(against, 0.0) + 2 * WPNAV_DT)
        return self.flights.fly(
            legs[k], limit, accel, self.drone.entry, exit_max, self.settings.tracking,
            self.drone.state, max_time,
        )  # fmt: skip

    def fastest(self, max_speed: float) -> float:
        """Duration with the binding limit at ``max_speed`` along the chord [s]."""
        share = float(np.linalg.norm(self.chord))
        if share == 0.0:
            return 0.0
        horizontal = float(np.hypot(self.chord[0], self.chord[1]))
        component = horizontal if self.axis == "horizontal" else abs(float(self.chord[2]))
        return self.fly(self.axis, max(max_speed * component / share, MIN_VERTICAL)).duration

    @property
    def vertical_capable(self) -> bool:
        """Whether the leg may be timed by its climb or descent limit."""
        rise = abs(float(self.chord[2]))
        length = float(np.linalg.norm(self.chord))
        return rise >= MIN_VERTICAL_EXTENT and rise >= MIN_VERTICAL_SHARE * length

    def slowest(self) -> float:
        """Longest duration ArduCopter can be made to fly it [s] (inf if unbounded)."""
        if self.axis != "horizontal" or self.climbs:
            return np.inf
        return self.fly("horizontal", MIN_GROUND_SPEED).duration

    def solve(self, target: float) -> tuple[str, float, str]:
        """The binding axis and value that fly the leg in ``target`` [s], and "", "early"
        or "late" where no value does."""
        axis, low = self.axis, (MIN_GROUND_SPEED if self.axis == "horizontal" else MIN_VERTICAL)
        duration = lambda axis, value: self.fly(axis, value, against=target).duration  # noqa: E731
        if axis == "horizontal" and duration(axis, low) < target and self.climbs:
            axis = self._vertical() if self.vertical_capable else f"{self._vertical()}/floor"
            low = MIN_VERTICAL
        high = MAX_LIMIT
        if duration(axis, low) < target:
            return axis, low, "early"
        if duration(axis, high) > target:
            return axis, high, "late"
        for _ in range(BISECTION_STEPS):
            middle = float(np.sqrt(low * high))  # geometric: limits span decades
            low, high = (middle, high) if duration(axis, middle) > target else (low, middle)
        return axis, high, ""


def solve_fleet(
    points: NDArray[np.float64],
    planned: NDArray[np.float64],
    settings: ArduCopterSettings,
    max_speed: float,
    min_durations: NDArray[np.float64] | None = None,
    flights: LegFlights | None = None,
) -> FleetSpeeds:
    """Times and limits for three drones' chains through ``points`` (K, 3, 3) planned at
    ``planned`` (K,) [s] (module docstring); ``min_durations`` (K-1,) are further lower
    bounds per leg (the platform's angular rate); ``flights``: the flights of earlier
    timings of the same plan, to reuse."""
    flights = flights or LegFlights()
    drones = [
        _Drone(legs_through(points[:, j]), vehicle_state(points[0, j]), settings.initial_speeds)
        for j in range(3)
    ]
    times = [0.0]
    shift = 0.0
    limits: list[list[SpeedLimits]] = [[], [], []]
    early, late = [], []
    for k in range(len(planned) - 1):
        problems = [_LegProblem(d, k, settings, flights) for d in drones]
        start = times[-1]
        shortest = max(
            p.fastest(max_speed) + d.start for p, d in zip(problems, drones, strict=True)
        )
        longest = min(p.slowest() + d.start for p, d in zip(problems, drones, strict=True))
        floor = start + (0.0 if min_durations is None else float(min_durations[k]))
        end = max(float(planned[k + 1]) + shift, shortest, floor)
        if longest >= max(shortest, floor):
            end = min(end, longest)
        shift = end - float(planned[k + 1])
        times.append(end)
        for j, (problem, drone) in enumerate(zip(problems, drones, strict=True)):
            axis, value, status = problem.solve(end - drone.start)
            flown = problem.fly(axis, value)
            drone.start += flown.duration
            drone.entry, drone.state = flown.exit_speed, flown.state
            drone.limits = _limit(settings.initial_speeds, axis, value)
            limits[j].append(drone.limits)
            if status == "early":
                early.append((j + 1, k + 1))
            elif status == "late":
                late.append((j + 1, k + 1))
    accel = settings.accel_limits
    chains = tuple(
        fly_chain(points[:, j], limits[j], accel, settings.initial_speeds, settings.tracking)
        for j in range(3)
    )
    return FleetSpeeds(
        np.array(times), tuple(tuple(row) for row in limits), chains, tuple(early), tuple(late)
    )
