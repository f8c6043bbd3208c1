"""The flyable plan: timed spline waypoints, each drone's speed limits per leg, and the
motion ArduCopter will fly with them (design.md section 9, ``missions.autopilots``).

1. **Waypoints**: the fewest whose straight legs keep the load safe
   (:func:`missions.trajectory.waypoints.reduce_to_waypoints`), as the autopilot stores them
   (:func:`stored_positions`); a set-down (:mod:`missions.trajectory.vertical_legs`) adds the goal
   itself after the raised goal the plan ends at, as a last, slow leg.
2. **Timing**: waypoint times and per-drone limits with which the modelled flights reach
   every waypoint together (:func:`missions.autopilots.speed_solver.solve_fleet`), no
   faster than the drone speed and platform angular rate limits allow.
3. **Check**: the load reconstructed from the three *modelled* targets every
   ``check_resolution`` seconds, against the plan at the formation's progress (the dense
   sample nearest the three drones: a delay all three share is harmless, a difference
   between them is not), must pass the same checks as the straight legs did; where it fails
   worst, the leg is split at the dense sample there, and timing and check run again. A
   set-down is checked for its collisions only, its surfaces excepted.
4. **Early legs** (a drone that should fly a level leg slower than ArduCopter's
   ground-speed floor, :mod:`missions.autopilots.ardupilot`; mostly the time law's slow
   ramps): a waypoint next to one is dropped where the check still passes.
5. **Tracking**: the same measure on the modelled *vehicles*, which lag their targets
   (:mod:`missions.autopilots.spline`), is reported, not enforced
   (``max_tracking_deviation``): splitting legs does not shorten a lag, and the plan's
   clearance (the position-error model) is what covers it.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from flycrane.model.cable_system import CableSystem
from flycrane.model.direct_kinematics import configuration_from_drone_positions
from flycrane.model.kinematics import drone_positions_from_configuration, matrix_from_tilt_torsion
from missions.autopilots.ardupilot import ArduCopterSettings
from missions.autopilots.speed_solver import FleetSpeeds, LegFlights, solve_fleet
from missions.autopilots.spline import SpeedLimits
from missions.geodesy import (
    DEGREE_UNIT,
    ardupilot_altitude,
    degrees_to_int,
    enu_from_geodetic,
    geodetic_from_enu,
)
from missions.options import MissionOptions
from missions.trajectory.motion import DroneMotion, formation_progress
from missions.trajectory.tracks import Track, rotation_angles
from missions.trajectory.vertical_legs import RAISE_STEP, VerticalLeg
from missions.trajectory.waypoints import LegCheck, SafetyCheck, check_flight, reduce_to_waypoints

#: Most splits of legs whose modelled flight failed its check, before giving up.
MAX_SPLITS = 40


@dataclass(frozen=True)
class SetDown:
    """The last leg of a plan that ends on a surface: when it is flown, and onto what."""

    leg: VerticalLeg
    start: float  #: mission time of the arrival at the raised goal [s]
    end: float  #: of the arrival on the goal [s]

    def as_dict(self) -> dict:
        return {**self.leg.as_dict(), "start_time": self.start, "end_time": self.end}

    @classmethod
    def from_dict(cls, data: dict) -> SetDown:
        """Inverse of :meth:`as_dict`."""
        return cls(VerticalLeg.from_dict(data), data["start_time"], data["end_time"])


@dataclass(frozen=True)
class FlightPlan:
    """Timed spline waypoints with each drone's speed limits (module docstring)."""

    ok: bool
    reason: str
    indices: NDArray[np.int64]  #: (K,) samples of the dense track used as waypoints
    time: NDArray[np.float64]  #: (W,) mission time of each waypoint [s from the release]
    q: NDArray[np.float64]  #: (W, 9) planned configurations at the waypoints
    drones: NDArray[np.float64]  #: (W, 3, 3) waypoints as the autopilot stores them [m]
    limits: tuple[tuple[SpeedLimits, ...], ...]  #: [drone][leg]
    motion: DroneMotion  #: what the autopilots will fly: their targets
    vehicles: DroneMotion  #: where the modelled vehicles following those targets will be
    settings: ArduCopterSettings
    early: tuple[tuple[int, int], ...]  #: (drone, leg) flown faster than planned (1-based)
    max_platform_deviation: float  #: over the modelled flight (the targets) [m]
    max_cable_length_error: float  #: [m]
    #: the same for the modelled vehicles, which lag their targets: what the check on the
    #: targets does not see (module docstring) [m]
    max_tracking_deviation: float
    track_time: NDArray[np.float64]  #: (K,) the dense plan's time at its waypoints
    set_down: SetDown | None = None  #: W = K + 1 with one, else W = K

    @property
    def duration(self) -> float:
        """Release to the end of the last leg [s]."""
        return float(self.time[-1])

    def progress_time(self, t: NDArray[np.float64]) -> NDArray[np.float64]:
        """The dense plan's time at mission times ``t``: linear between waypoints (held at
        the raised goal during a set-down)."""
        return np.interp(t, self.time[: len(self.track_time)], self.track_time)

    def retimed(self, track: Track) -> Track:
        """The dense plan on mission time (the inverse of :meth:`progress_time`), with the
        set-down's descent to the goal at its end if there is one, sampled every
        :data:`~missions.trajectory.vertical_legs.RAISE_STEP` as the descent was checked."""
        mission = np.interp(track.time, self.track_time, self.time[: len(self.track_time)])
        if self.set_down is None:
            return Track(mission, track.q, track.drones)
        steps = max(1, int(np.ceil(self.set_down.leg.height / RAISE_STEP - 1e-9)))
        f = np.linspace(0.0, 1.0, steps + 1)[1:]
        return Track(
            np.append(mission, mission[-1] + f * (self.time[-1] - mission[-1])),
            np.concatenate([track.q, track.q[-1] + f[:, None] * (self.q[-1] - track.q[-1])]),
            np.concatenate(
                [
                    track.drones,
                    track.drones[-1] + f[:, None, None] * (self.drones[-1] - track.drones[-1]),
                ]
            ),
        )


def stored_positions(enu: NDArray[np.float64], options: MissionOptions) -> NDArray[np.float64]:
    """ENU positions (..., 3) as ArduPilot flies them: latitude and longitude rounded to
    1e-7 degree (about 1 cm), altitudes truncated to whole centimetres. Speeds planned for
    unrounded positions would be off by the rounding: on a leg that moves centimetres in one
    direction, by tens of percent in that direction's limit."""
    origin = options.origin
    lat, lon, amsl = geodetic_from_enu(enu, origin)
    stored = ardupilot_altitude(options.item_altitude(np.asarray(enu, dtype=float)[..., 2], amsl))
    return enu_from_geodetic(
        degrees_to_int(lat) * DEGREE_UNIT,
        degrees_to_int(lon) * DEGREE_UNIT,
        options.item_amsl(stored),
        origin,
    )


def _angular_floor(q: NDArray[np.float64], options: MissionOptions) -> NDArray[np.float64]:
    """Shortest leg durations allowed by the platform's angular rate limit (K-1,) [s]."""
    return rotation_angles(matrix_from_tilt_torsion(q[:, 3:6])) / options.max_angular_rate


@dataclass(frozen=True)
class _Waypoints:
    """Waypoints at dense samples ``indices``, plus the set-down's goal if there is one."""

    indices: NDArray[np.int64]
    q: NDArray[np.float64]  #: (W, 9)
    drones: NDArray[np.float64]  #: (W, 3, 3) as stored
    planned: NDArray[np.float64]  #: (W,) planned times [s]


def _waypoints(
    system: CableSystem,
    track: Track,
    indices: NDArray[np.int64],
    options: MissionOptions,
    set_down: VerticalLeg | None,
) -> _Waypoints:
    q, planned = track.q[indices], track.time[indices]
    if set_down is not None:
        q = np.concatenate([q, set_down.low[None]])
        planned = np.append(planned, planned[-1] + set_down.height / options.vertical_leg_speed)
    drones = stored_positions(drone_positions_from_configuration(system, q), options)
    return _Waypoints(indices, q, drones, planned)


@dataclass(frozen=True)
class _Attempt:
    """One timing of a set of waypoints, its modelled motion, and its check."""

    waypoints: _Waypoints
    fleet: FleetSpeeds
    motion: DroneMotion
    check: LegCheck  #: up to the raised goal
    times: NDArray[np.float64]  #: check times [s]
    progress: NDArray[np.float64]  #: the dense plan's time at each check time [s]
    set_down_safe: bool

    def badness(self, options: MissionOptions) -> NDArray[np.float64]:
        badness = np.maximum(
            self.check.platform_deviation / options.max_platform_deviation,
            self.check.cable_length_error / options.max_cable_length_error,
        )
        return np.where(self.check.valid, badness, np.inf)

    def passes(self, options: MissionOptions) -> bool:
        return bool(self.badness(options).max() <= 1.0) and self.set_down_safe


def _attempt(
    system: CableSystem,
    track: Track,
    waypoints: _Waypoints,
    validity: SafetyCheck,
    landing: SafetyCheck,
    options: MissionOptions,
    settings: ArduCopterSettings,
    flights: LegFlights,
) -> _Attempt:
    """Timing for ``waypoints``, the modelled motion, and its check every
    ``check_resolution`` (module docstring); ``landing`` judges the set-down leg;
    ``flights`` are those of the plan's earlier attempts."""
    fleet = solve_fleet(
        waypoints.drones,
        waypoints.planned,
        settings,
        options.max_drone_speed,
        _angular_floor(waypoints.q, options),
        flights,
    )
    motion = DroneMotion.from_chains(fleet.flights, fleet.times)
    step = options.check_resolution
    dense_end = float(fleet.times[len(waypoints.indices) - 1])
    times = np.arange(0.0, dense_end + step / 2, step)
    flown = motion.at(times)
    progress = formation_progress(track.time, track.drones, flown)
    check = check_flight(system, track, flown, progress, validity)
    set_down_safe = True
    if len(fleet.times) > len(waypoints.indices):  # a set-down: collisions only
        during = np.arange(dense_end, float(fleet.times[-1]) + step / 2, step)
        rebuilt = configuration_from_drone_positions(
            system, motion.at(during), initial=np.repeat(waypoints.q[-2:-1], len(during), 0)
        )
        set_down_safe = bool(np.all(rebuilt.converged & landing(rebuilt.q)))
    return _Attempt(waypoints, fleet, motion, check, times, progress, set_down_safe)


def plan_flight(
    system: CableSystem,
    track: Track,
    validity: SafetyCheck,
    options: MissionOptions,
    settings: ArduCopterSettings | None = None,
    set_down: VerticalLeg | None = None,
    landing: SafetyCheck | None = None,
) -> FlightPlan:
    """Waypoints, timing and limits for the three drones (module docstring); a
    ``set_down`` is judged by ``landing`` (the validity without its surfaces)."""
    settings = settings or ArduCopterSettings.for_acceleration(options.autopilot_acceleration)
    landing = landing or validity
    straight = reduce_to_waypoints(system, track, validity, options)
    indices = straight.indices
    reason = straight.reason

    flights = LegFlights()  # attempts differ in a waypoint: the legs before it repeat

    def attempt(indices: NDArray[np.int64]) -> _Attempt:
        waypoints = _waypoints(system, track, indices, options, set_down)
        return _attempt(system, track, waypoints, validity, landing, options, settings, flights)

    for _ in range(MAX_SPLITS + 1):
        trial = attempt(indices)
        badness = trial.badness(options)
        if trial.passes(options) or not straight.ok:
            break
        if badness.max() <= 1.0:  # only the set-down fails: nothing to split there
            reason = "the set-down leg touches more than its surfaces"
            break
        worst = int(np.argmax(badness))
        sample = int(np.clip(np.searchsorted(track.time, trial.progress[worst]), 1,
                             len(track.time) - 2))  # fmt: skip
        if sample in indices:
            reason = (
                f"the modelled flight fails its check at {trial.times[worst]:.2f} s, "
                "on a leg that cannot be split further"
            )
            break
        indices = np.sort(np.append(indices, sample))
    else:
        reason = f"the modelled flight still fails its check after {MAX_SPLITS} splits"
    if not reason and straight.ok:
        trial = _merge_early_legs(trial, attempt, options)
    fleet, waypoints = trial.fleet, trial.waypoints
    vehicles = DroneMotion.from_chains(fleet.flights, fleet.times, vehicles=True)
    lagging = vehicles.at(trial.times)
    progress = formation_progress(track.time, track.drones, lagging)
    tracking = check_flight(system, track, lagging, progress, validity)
    return FlightPlan(
        ok=straight.ok and not reason,
        reason=reason,
        indices=waypoints.indices,
        time=fleet.times,
        q=waypoints.q,
        drones=waypoints.drones,
        limits=fleet.limits,
        motion=trial.motion,
        vehicles=vehicles,
        settings=settings,
        early=fleet.early,
        max_platform_deviation=float(trial.check.platform_deviation.max()),
        max_cable_length_error=float(trial.check.cable_length_error.max()),
        max_tracking_deviation=float(tracking.platform_deviation.max()),
        track_time=track.time[waypoints.indices],
        set_down=None
        if set_down is None
        else SetDown(set_down, float(fleet.times[-2]), float(fleet.times[-1])),
    )


def _merge_early_legs(
    trial: _Attempt, attempt: Callable[[NDArray[np.int64]], _Attempt], options: MissionOptions
) -> _Attempt:
    """Drop a waypoint next to a leg some drone flies early while that leaves fewer early
    legs and the check still passes: such legs are mostly the time law's slow ramps, which
    a longer leg flies at a settable speed (the autopilot accelerates and brakes by
    itself). The first and last dense waypoints stay."""
    for _ in range(len(trial.waypoints.indices)):
        early = trial.fleet.early
        if not early:
            break
        leg = early[0][1] - 1  # 0-based leg k runs from waypoint k to k + 1
        last = len(trial.waypoints.indices) - 1
        for drop in (leg + 1, leg):  # its end, else its start
            if not 0 < drop < last:
                continue
            candidate = attempt(np.delete(trial.waypoints.indices, drop))
            if len(candidate.fleet.early) < len(early) and candidate.passes(options):
                trial = candidate
                break
        else:
            break
    return trial
