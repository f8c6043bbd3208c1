"""The flight report: how a recorded flight went against its plan, and whether it was safe.

For each source of positions (the autopilots' estimates and, from a simulator, the truth),
on mission time (:mod:`.alignment`) at :data:`REPORT_RATE_HZ`, against the plan's
*modelled* drones (where :mod:`missions.autopilots` says each vehicle will be, lagging its
autopilot's target as a copter does):

- **timing** (:mod:`.timing`): the flown duration against the plan's, the start spread,
  the release spread, each drone's *progress* along the plan and how far apart the drones
  are in it;
- **geometry**: each drone's distance from its modelled position at the same mission time
  and from its modelled path (at its own progress); the error of the three inter-drone
  distances against the plan at the formation's progress (the plan time whose three drone
  positions are nearest the flown ones), which a delay common to all three leaves alone,
  and the same at one common time (the drones' own clocks, SYSTEM_TIME: the measure of
  being in step);
- **the load**: the configuration reconstructed from the three drones (direct kinematics,
  started from the plan at the formation's progress), its statics (least slack, overload
  and thrust margins, highest cost) and its collisions with the *real* obstacles (no
  planning clearance): the least clearance, between which bodies, and when.

The verdict (:class:`Verdict`) is safe when every reconstructed configuration of the
safety source (the truth where there is one) is feasible and collision-free, the drones
were released within the plan's start-offset tolerance, and every vehicle flew with the
parameters the plan assumes (when the flight says so): the load itself, and the two
conditions the plan's timing tolerance rests on. Drones apart in progress by more than
that tolerance (p95) are a *warning*, not a verdict: progress is the nearest point of a
drone's own path, so it mixes timing with the drone's distance from that path and grows
as speed falls (BENCHMARKS.md, "Moved from code comments"); the load's own geometry is
the evidence that counts. So is a formation that sat at rest, on median, further from the
plan than the position-error model's common bounds allow: the clearance the plan kept rests
on them, and a steady offset of all three drones is a frame error (a wrong home height,
BENCHMARKS.md "Home height") or a steady push.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import asdict, dataclass, field
from functools import partial
from typing import Any

import numpy as np
from numpy.typing import NDArray

from flycrane.model.cost import cost_from_report
from flycrane.model.direct_kinematics import configuration_from_drone_positions
from flycrane.model.statics import evaluate_statics
from missions.export.formats import finite
from missions.flight_report.alignment import Releases
from missions.flight_report.planned_flight import PlannedFlight
from missions.flight_report.timing import (
    END_MARGIN_S,
    REPORT_RATE_HZ,
    Timing,
    flight_timing,
    flown_at,
    motion_end,
    p95,
)
from missions.flight_report.vehicle_log import PositionSeries, VehicleLog
from missions.position_error import position_error_model
from missions.trajectory.motion import forward_progress

#: The model has the drones at rest below this speed [m/s] (:func:`_common_offset_at_rest`).
REST_SPEED = 0.02
#: A drone is at rest when it moves less than this [m/s] over :data:`STOP_WINDOW_S` [s]
#: (SIM_STATE's positions come in centimetre steps: a shorter window is noise).
STOPPED_SPEED, STOP_WINDOW_S = 0.1, 0.5


@dataclass(frozen=True)
class SourceFigures:
    """Every figure of one position source (module docstring). Lengths [m], times [s]."""

    source: str  #: "estimated" or "true"
    samples: int
    rate_hz: float
    error_in_time_p95: tuple[float, float, float]  #: per drone, at the same mission time
    error_in_time_max: tuple[float, float, float]
    error_off_path_p95: tuple[float, float, float]  #: per drone, at its own progress
    error_off_path_max: tuple[float, float, float]
    inter_drone_error_p95: float
    inter_drone_error_max: float
    #: the three distances' error against the plan's at the same mission time, the worst
    #: pair per sample (p95, max): the drones in step on one clock
    pair_error_common_p95: float
    pair_error_common_max: float
    #: where the whole formation sat against the plan while the model has it at rest (the
    #: hold at the release, stops, the final hold): the median of the three drones' mean
    #: displacement, ENU, over those samples (NaN without any). A frame error common to the
    #: drones (home altitude, origin) shows here, and the load moves with it; in motion the
    #: drones' lag along the path would mix in (BENCHMARKS.md, "Home height")
    common_offset_at_rest: tuple[float, float, float]
    converged: bool  #: every reconstruction converged
    feasible: bool  #: every reconstruction wrench- and thrust-feasible
    collision_free: bool  #: against the real obstacles
    unsafe_samples: int
    first_unsafe: str  #: "" or "at 3.20 s: <why>"
    least_slack_margin: float  #: min over samples and cables of t_lo - f_lo [N]
    least_overload_margin: float  #: f_hi - t_hi [N]
    least_thrust_margin: float  #: h - m [N]
    highest_cost: float
    least_clearance: float  #: [m], negative: penetration
    least_clearance_bodies: str  #: "footbridge 0.031 m from building east"
    least_clearance_at: float  #: mission time [s]


@dataclass(frozen=True)
class Verdict:
    safe: bool
    reasons: tuple[str, ...]  #: why not (empty when safe)
    warnings: tuple[str, ...] = ()  #: what a person should look at even so

    def __str__(self) -> str:
        text = "SAFE" if self.safe else "UNSAFE: " + "; ".join(self.reasons)
        return text + "".join(f" (warning: {w})" for w in self.warnings)


@dataclass(frozen=True)
class TeamStop:
    """How a team stop went (:mod:`missions.execution.team`), on mission time [s]."""

    detected_after: float | None  #: from the fault to the stop command (None: not injected)
    commanded_at: float
    #: per drone, from the command until it came to rest (its speed over
    #: :data:`STOP_WINDOW_S` below :data:`STOPPED_SPEED`); inf: it never did
    at_rest_after: tuple[float, float, float]


@dataclass(frozen=True)
class FlightReport:
    """What a flight did against its plan; :meth:`as_dict` is the JSON."""

    mode: str  #: who flew it: missions, stream or onboard (:mod:`missions.execution`)
    stop: TeamStop | None  #: a team stop, if one went out
    planned_duration: float
    release_spread: float
    start_offset_tolerance: float  #: what the plan claimed
    timing: Timing
    estimated: SourceFigures
    true: SourceFigures | None
    verdict: Verdict
    parameter_differences: tuple[str, ...] = ()
    release_log_time: float = 0.0  #: mission time 0 [s since the Unix epoch, the log's clock]
    series: dict[str, dict[str, list[Any]]] = field(default_factory=dict, repr=False)

    def as_dict(self) -> dict[str, Any]:
        """Every figure, JSON's way: a figure that is not finite (the cost of a load no
        cable can hold) is None."""
        document: dict[str, Any] = finite(asdict(self))
        return document


def _pairwise(drones: NDArray[np.float64]) -> NDArray[np.float64]:
    """Distances 1-2, 2-3, 3-1 of (N, 3, 3) drone positions, (N, 3)."""
    return np.linalg.norm(drones - np.roll(drones, -1, axis=1), axis=-1)


def _finite(value: float) -> float | None:
    return float(value) if np.isfinite(value) else None


def _per_drone(values: NDArray[np.float64]) -> tuple[float, float, float]:
    return (float(values[0]), float(values[1]), float(values[2]))


def _common_offset_at_rest(
    t: NDArray[np.float64], modelled: NDArray[np.float64], displacement: NDArray[np.float64]
) -> NDArray[np.float64]:
    """:attr:`SourceFigures.common_offset_at_rest` of displacements (N, 3 drones, 3) from
    the ``modelled`` drones at times ``t``."""
    if len(t) < 2:
        return np.full(3, np.nan)
    speed = np.linalg.norm(np.gradient(modelled, t, axis=0), axis=-1).max(axis=1)
    at_rest = speed < REST_SPEED
    if not at_rest.any():
        return np.full(3, np.nan)
    return np.median(displacement[at_rest].mean(axis=1), axis=0)


def _source_figures(
    source: str,
    plan: PlannedFlight,
    tracks: Sequence[PositionSeries],
    releases: Releases,
    t: NDArray[np.float64],
) -> tuple[SourceFigures, dict[str, list[Any]]]:
    problem = plan.problem
    system = problem.system
    plan_t, plan_drones = plan.progress_samples()
    flown = flown_at(tracks, releases, t)
    modelled = plan.drones_at(t)
    back = partial(forward_progress, backward=plan.reversible)
    displacement = flown - modelled  # (N, 3 drones, 3)
    in_time = np.linalg.norm(displacement, axis=-1)  # (N, 3)
    off_path = np.stack(
        [
            np.linalg.norm(
                plan_drones[back(plan_drones[:, k], flown[:, k]), k] - flown[:, k],
                axis=-1,
            )
            for k in range(3)
        ],
        axis=1,
    )
    formation = back(plan_drones.reshape(len(plan_t), 9), flown.reshape(-1, 9))
    inter = np.abs(_pairwise(flown) - _pairwise(plan_drones[formation])).max(axis=1)
    common = np.abs(_pairwise(flown) - _pairwise(modelled)).max(axis=1)

    initial = plan.configurations_at(plan_t[formation])
    rebuilt = configuration_from_drone_positions(system, flown, initial=initial)
    statics = evaluate_statics(system, rebuilt.q)
    feasible = statics.feasible & rebuilt.converged
    # Each sample against the real obstacles, but for the surfaces a lift-off or set-down
    # is meant to touch during its window.
    surfaces = [(), *(w.surfaces for w in plan.contact_windows)]
    checkers = {s: plan.real_validity(s) for s in set(surfaces)}
    which = [next((w.surfaces for w in plan.contact_windows if w.start <= x <= w.end), ())
             for x in t]  # fmt: skip
    free = np.zeros(len(t), dtype=bool)
    closest = []
    for n, q in enumerate(rebuilt.q):
        checker = checkers[which[n]]
        free[n] = bool(feasible[n] and checker.collision.collision_free(q)[0])
        closest.append(checker.collision.closest(q))
    safe = feasible & free
    distance = np.array([c.distance for c in closest])
    worst = int(np.argmin(distance))
    first_unsafe = ""
    if not safe.all():
        n = int(np.flatnonzero(~safe)[0])
        reason = checkers[which[n]].explain(rebuilt.q[n])
        first_unsafe = f"at {t[n]:.2f} s: {reason if rebuilt.converged[n] else 'no pose fits'}"
    finite = np.isfinite(statics.slack_margin).all(axis=1)
    figures = SourceFigures(
        source=source,
        samples=len(t),
        rate_hz=REPORT_RATE_HZ,
        error_in_time_p95=_per_drone(np.percentile(in_time, 95, axis=0)),
        error_in_time_max=_per_drone(in_time.max(axis=0)),
        error_off_path_p95=_per_drone(np.percentile(off_path, 95, axis=0)),
        error_off_path_max=_per_drone(off_path.max(axis=0)),
        inter_drone_error_p95=p95(inter),
        inter_drone_error_max=float(inter.max()),
        pair_error_common_p95=p95(common),
        pair_error_common_max=float(common.max()),
        common_offset_at_rest=_per_drone(_common_offset_at_rest(t, modelled, displacement)),
        converged=bool(rebuilt.converged.all()),
        feasible=bool(feasible.all()),
        collision_free=bool(free[feasible].all()),
        unsafe_samples=int((~safe).sum()),
        first_unsafe=first_unsafe,
        least_slack_margin=float(statics.slack_margin[finite].min(initial=np.inf)),
        least_overload_margin=float(statics.overload_margin[finite].min(initial=np.inf)),
        least_thrust_margin=float(statics.thrust_margin[finite].min(initial=np.inf)),
        highest_cost=float(cost_from_report(system, statics).max()),
        least_clearance=float(distance[worst]),
        least_clearance_bodies=str(closest[worst]),
        least_clearance_at=float(t[worst]),
    )
    series = {
        "drones_enu": flown.tolist(),
        "configurations": rebuilt.q.tolist(),
        "error_in_time": in_time.tolist(),
        "inter_drone_error": inter.tolist(),
        "pair_error_common": common.tolist(),
        "slack_margin": statics.slack_margin.min(axis=1).tolist(),
        "overload_margin": statics.overload_margin.min(axis=1).tolist(),
        "thrust_margin": statics.thrust_margin.min(axis=1).tolist(),
        "clearance": distance.tolist(),
        "safe": safe.tolist(),
    }
    return figures, series


def _team_stop(
    plan: PlannedFlight,
    vehicles: Sequence[VehicleLog],
    releases: Releases,
    commanded: float,
    struck: float | None,
) -> TeamStop:
    """When each drone came to rest after a team stop commanded at mission time
    ``commanded`` (true positions where there are, else estimates)."""
    window = STOP_WINDOW_S
    rests = []
    for k, vehicle in enumerate(vehicles):
        track = vehicle.true or vehicle.estimated
        t = np.arange(commanded, releases.mission_time(k, track.time[-1:])[0] - window, 0.05)
        at = releases.vehicle_time_of(k, t)
        speed = np.linalg.norm(track.at(at + window) - track.at(at), axis=-1) / window
        still = np.flatnonzero(speed <= STOPPED_SPEED)
        rests.append(float(t[still[0]] - commanded) if still.size else math.inf)
    return TeamStop(
        detected_after=None if struck is None else commanded - struck,
        commanded_at=commanded,
        at_rest_after=(rests[0], rests[1], rests[2]),
    )


def _short_logs(
    plan: PlannedFlight,
    vehicles: Sequence[VehicleLog],
    releases: Releases,
    judge_until: float | None,
) -> list[tuple[str, float, float]]:
    """The drones whose logs end before the flight they must show: (name, where the log
    ends, where it had to reach) [s of mission time]. A flight must be recorded to its
    planned end of motion, a stopped one to :data:`END_MARGIN_S` before ``judge_until``
    (the drones at rest by then)."""
    needed = motion_end(plan) if judge_until is None else judge_until - END_MARGIN_S
    short = []
    for k, vehicle in enumerate(vehicles):
        end = float(releases.mission_time(k, vehicle.estimated.time[-1:])[0])
        if end < needed:
            short.append((vehicle.name, end, needed))
    return short


def flight_report(
    plan: PlannedFlight,
    vehicles: Sequence[VehicleLog],
    releases: Releases,
    parameter_differences: Sequence[str] = (),
    stop: tuple[float, float | None] | None = None,
    judge_after_stop: float = 3.0,
    judge_all: bool = False,
) -> FlightReport:
    """The report of a flight (module docstring). ``stop``: (mission time the team stop was
    commanded, mission time of the fault that caused it): the flight is judged through the
    stop and ``judge_after_stop`` [s] of the hold after it, or to its end (``judge_all``,
    e.g. after a retreat)."""
    judge_until = plan.duration if judge_all else None
    if stop is not None and not judge_all:
        judge_until = stop[0] + judge_after_stop
    short = _short_logs(plan, vehicles, releases, judge_until)
    if short:  # judged while every drone was recorded: a log's last fix is not its flight
        judge_until = min(end for _, end, _ in short)
    timing, t, progress = flight_timing(plan, vehicles, releases, judge_until)
    estimated, estimated_series = _source_figures(
        "estimated", plan, [v.estimated for v in vehicles], releases, t
    )
    true: SourceFigures | None = None
    true_series: dict[str, list[Any]] = {}
    truths = [v.true for v in vehicles if v.true is not None]
    if len(truths) == len(vehicles):
        true, true_series = _source_figures("true", plan, truths, releases, t)
    tolerance = float(plan.timing_tolerance["start_offset"])
    judged = true or estimated
    reasons = []
    if not (judged.feasible and judged.collision_free and judged.converged):
        reasons.append(f"{judged.source} positions: unsafe load {judged.first_unsafe}")
    if plan.mode == "missions" and releases.spread > tolerance:
        reasons.append(
            f"release spread {releases.spread:.3f} s beyond the plan's {tolerance:.3f} s"
        )
    reasons += [f"parameter: {p}" for p in parameter_differences]
    reasons += [
        f"{name}'s log ends at {end:.2f} s of mission time, before {needed:.2f} s: the flight "
        "after it is not judged"
        for name, end, needed in short
    ]
    warnings = []
    model = position_error_model(plan.task.mission.position_error)
    east, north, up = judged.common_offset_at_rest
    if math.hypot(east, north) > model.common_horizontal or abs(up) > model.common_vertical:
        warnings.append(
            f"at rest the formation sat ({east:+.3f}, {north:+.3f}, {up:+.3f}) m (east, "
            f"north, up; median) from the plan, beyond the position-error model's common "
            f"{model.common_horizontal:.3f} m horizontally and {model.common_vertical:.3f} m "
            "vertically: a frame error (home height, origin) or a steady push moves the load"
        )
    if plan.mode == "missions" and timing.progress_spread_p95 > tolerance:
        warnings.append(
            f"drones {timing.progress_spread_p95:.3f} s apart in progress (p95), beyond the "
            f"plan's {tolerance:.3f} s"
        )
    return FlightReport(
        mode=plan.mode,
        stop=None if stop is None else _team_stop(plan, vehicles, releases, *stop),
        planned_duration=plan.nominal_duration or plan.duration,
        release_spread=releases.spread,
        start_offset_tolerance=tolerance,
        timing=timing,
        estimated=estimated,
        true=true,
        verdict=Verdict(not reasons, tuple(reasons), tuple(warnings)),
        parameter_differences=tuple(parameter_differences),
        release_log_time=releases.log_time,
        series={
            "time": {"mission": t.tolist()},
            "progress": {"plan_time": [[_finite(p) for p in row] for row in progress]},
            "estimated": estimated_series,
            "true": true_series,
        },
    )
