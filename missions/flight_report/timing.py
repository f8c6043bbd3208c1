"""When the drones flew what, on mission time: each drone's start and arrival against its
modelled drone's, its progress along the plan, and the report's sample times.

A clocked execution's start and arrival are read as the time shift that best lays the
drone's first or last :data:`SHIFT_WINDOW_S` of motion over its model's: a drone starts
from rest and comes to rest slowly, so a threshold crossing would be the estimate's noise
over the last or first centimetres (the plan itself takes most of a second over its last
2 cm). Missions arrive when the autopilot says its last leg is done.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from missions.flight_report.alignment import Releases
from missions.flight_report.planned_flight import PROGRESS_STEP_S, PlannedFlight
from missions.flight_report.vehicle_log import PositionSeries, VehicleLog

#: Reconstructions per second of mission time (a report must give at least 5 Hz).
REPORT_RATE_HZ = 10.0
#: A drone has arrived when it is this much closer to its last waypoint than where it
#: settles in the hold after it [m] (an estimate may settle centimetres off the target).
ARRIVAL_TOLERANCE_M = 0.02
#: Progress is defined where the drone's modelled speed is at least this [m/s]: a
#: hovering drone is equally near every instant of its hover, and a slow one's progress is
#: dominated by the position estimate's noise (2 cm at 10 cm/s is 0.2 s).
MOVING_SPEED = 0.2
#: After the last arrival, this much of the hold is judged too [s].
END_MARGIN_S = 1.0
#: The start and the end are read from this much of the first and the last motion [s],
#: shifted by up to :data:`SHIFT_SEARCH_S` [s].
SHIFT_WINDOW_S, SHIFT_SEARCH_S = 3.0, 0.5


def p95(values: NDArray[np.float64]) -> float:
    """The 95th percentile of ``values``; 0 of none."""
    return float(np.percentile(values, 95)) if values.size else 0.0


@dataclass(frozen=True)
class Timing:
    """When the drones flew what, from the autopilots' own estimates (the truth differs by
    the estimation error, not in timing). Times [s] of mission time."""

    flown_duration: float  #: the last drone's arrival
    arrival: tuple[float, float, float]  #: per drone
    progress_spread_max: float  #: drones apart in progress along the plan
    progress_spread_p95: float
    #: how far apart the drones started [s]: each drone's first motion from where it held,
    #: against its modelled drone's (:func:`start_delays`)
    start_spread: float


def arrivals(
    plan: PlannedFlight, vehicles: Sequence[VehicleLog], releases: Releases
) -> list[float]:
    """Each drone's arrival at the end of its mission on mission time. Of missions: when
    its final hold became current (the autopilot's own judgement that the last leg is
    done). Of a clocked execution (``stream``, ``onboard``): the end of its modelled motion
    shifted by its :func:`end_delays`. Failing either (a stopped flight), when it came
    within :data:`ARRIVAL_TOLERANCE_M` of where it settled at the end."""
    end = plan.motion.drones[-1]
    clocked = None
    if plan.mode != "missions":
        clocked = motion_end(plan) + end_delays(plan, vehicles, releases)
    arrival = []
    for k, vehicle in enumerate(vehicles):
        event = vehicle.current.first(plan.end_seq[k]) if clocked is None else None
        if event is not None:
            arrival.append(float(releases.mission_time(k, np.array([event[0]]))[0]))
            continue
        if clocked is not None and np.isfinite(clocked[k]):
            arrival.append(float(clocked[k]))
            continue
        track = vehicle.estimated
        t = releases.mission_time(k, track.time)
        distance = np.linalg.norm(track.enu - end[k], axis=-1)
        near = (t >= 0.0) & (distance <= distance[-1] + ARRIVAL_TOLERANCE_M)
        arrival.append(float(t[np.argmax(near)]) if near.any() else np.inf)
    return arrival


def flown_at(
    tracks: Sequence[PositionSeries], releases: Releases, t: NDArray[np.float64]
) -> NDArray[np.float64]:
    """Drone positions (N, 3, 3) at mission times ``t``."""
    return np.stack(
        [track.at(releases.vehicle_time_of(k, t)) for k, track in enumerate(tracks)], axis=1
    )


def _progress(
    plan: PlannedFlight, flown: NDArray[np.float64], t: NDArray[np.float64]
) -> NDArray[np.float64]:
    """Each drone's progress (N, 3): mission time minus its lag along its modelled velocity
    at the same mission time; NaN where the model moves slower than :data:`MOVING_SPEED`
    (a hovering drone is equally near every instant of its hover)."""
    step = PROGRESS_STEP_S
    modelled = plan.drones_at(t)
    velocity = (plan.drones_at(t + step / 2) - plan.drones_at(t - step / 2)) / step
    speed2 = np.einsum("nka,nka->nk", velocity, velocity)
    along = np.einsum("nka,nka->nk", flown - modelled, velocity)
    moving = speed2 >= MOVING_SPEED**2
    lag = np.divide(along, speed2, out=np.zeros_like(along), where=moving)
    return np.where(moving, t[:, None] + lag, np.nan)


def motion_end(plan: PlannedFlight) -> float:
    """Mission time at which the modelled drones stop for good [s]."""
    drones = plan.motion.drones
    moving = (drones != drones[-1]).any(axis=(1, 2))
    if not moving.any():
        return 0.0
    return float(plan.motion.time[min(int(np.flatnonzero(moving)[-1]) + 1, len(moving) - 1)])


def _shift(
    plan: PlannedFlight,
    k: int,
    t: NDArray[np.float64],
    flown: NDArray[np.float64],
    window: NDArray[np.bool_],
    rest: NDArray[np.bool_],
    at: float,
) -> float:
    """The shift of mission time [s] that best lays drone k's motion in ``window`` over
    its modelled drone's, least squares on the log's full rate; each measured from where it
    rests (the flown drone over ``rest``, the model at mission time ``at``): a steady
    offset is not a delay. NaN without samples."""
    if not window.any() or not rest.any():
        return float("nan")
    moved = flown[window] - flown[rest].mean(axis=0)
    reference = plan.drones_at(np.array([at]))[0, k]
    shifts = np.arange(-SHIFT_SEARCH_S, SHIFT_SEARCH_S + 1e-9, 0.002)
    costs = [
        float(np.sum((moved - (plan.drones_at(t[window] - s)[:, k] - reference)) ** 2))
        for s in shifts
    ]
    return float(shifts[int(np.argmin(costs))])


def start_delays(
    plan: PlannedFlight, vehicles: Sequence[VehicleLog], releases: Releases
) -> NDArray[np.float64]:
    """Each drone's start against its modelled drone's [s]: the :func:`_shift` of its first
    :data:`SHIFT_WINDOW_S` of motion from its hold; a start from rest is slow, so a shift
    read from one threshold crossing would be the estimate's noise over a few millimetres
    per second."""
    delays = np.full(len(vehicles), np.nan)
    for k, vehicle in enumerate(vehicles):
        series = vehicle.estimated
        t = releases.mission_time(k, series.time)
        window, rest = (t > 0.0) & (t <= SHIFT_WINDOW_S), (t > -1.0) & (t <= 0.0)
        delays[k] = _shift(plan, k, t, series.enu, window, rest, 0.0)
    return delays


def end_delays(
    plan: PlannedFlight, vehicles: Sequence[VehicleLog], releases: Releases
) -> NDArray[np.float64]:
    """Each drone's arrival against its modelled drone's [s]: the :func:`_shift` of its
    last :data:`SHIFT_WINDOW_S` of motion to where it rests after it, for the same reason
    as :func:`start_delays` (the last centimetres are flown slowest)."""
    end = motion_end(plan)
    delays = np.full(len(vehicles), np.nan)
    for k, vehicle in enumerate(vehicles):
        series = vehicle.estimated
        t = releases.mission_time(k, series.time)
        window = (t > end - SHIFT_WINDOW_S) & (t <= end + SHIFT_SEARCH_S)
        rest = (t > end + SHIFT_SEARCH_S) & (t <= end + SHIFT_SEARCH_S + 1.0)
        delays[k] = _shift(plan, k, t, series.enu, window, rest, end)
    return delays


def flight_timing(
    plan: PlannedFlight,
    vehicles: Sequence[VehicleLog],
    releases: Releases,
    judge_until: float | None = None,
) -> tuple[Timing, NDArray[np.float64], NDArray[np.float64]]:
    """Timing, the report's mission times and each drone's progress there (N, 3); samples
    end at ``judge_until`` when given (a stopped flight), else after the last arrival."""
    tracks = [v.estimated for v in vehicles]
    arrival = arrivals(plan, vehicles, releases)
    last = max(arrival)
    horizon = (last if np.isfinite(last) else plan.duration * 2.0) + END_MARGIN_S
    if judge_until is not None:
        horizon = judge_until
    t = np.arange(0.0, horizon, 1.0 / REPORT_RATE_HZ)
    flown = flown_at(tracks, releases, t)
    progress = _progress(plan, flown, t)
    defined = np.isfinite(progress).sum(axis=1) >= 2  # two drones moving: a spread
    spread = np.nanmax(progress[defined], axis=1) - np.nanmin(progress[defined], axis=1)
    start = start_delays(plan, vehicles, releases)
    timing = Timing(
        flown_duration=last,
        arrival=(arrival[0], arrival[1], arrival[2]),
        progress_spread_max=float(spread.max(initial=0.0)),
        progress_spread_p95=p95(spread),
        start_spread=float(np.nanmax(start) - np.nanmin(start)),
    )
    return timing, t, progress
