"""The flyable plan: timed spline waypoints, each drone's speed limits per leg, and the
motion ArduCopter will fly with them (design.md section 9, ``missions.autopilots``).

1. **Waypoints**: the fewest whose straight legs keep the load safe
   (:func:`missions.trajectory.waypoints.reduce_to_waypoints`), as the autopilot stores them
   (:func:`~missions.trajectory.waypoints.stored_positions`); a set-down
   (:mod:`missions.trajectory.vertical_legs`) adds the goal itself after the raised goal the
   plan ends at, as a last, slow leg.
Steps 2 to 4 are one attempt each (:mod:`missions.trajectory.modelled_flight`):

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

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from flycrane.model.cable_system import CableSystem
from missions.autopilots.ardupilot import ArduCopterSettings
from missions.autopilots.speed_solver import LegFlights
from missions.autopilots.spline import SpeedLimits
from missions.options import MissionOptions
from missions.trajectory.modelled_flight import ModelledFlight, merge_early_legs, model_flight
from missions.trajectory.motion import DroneMotion, formation_progress
from missions.trajectory.tracks import Track
from missions.trajectory.vertical_legs import RAISE_STEP, VerticalLeg
from missions.trajectory.waypoints import (
    SafetyCheck,
    check_flight,
    reduce_to_waypoints,
    stored_waypoints,
)

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

    def attempt(indices: NDArray[np.int64]) -> ModelledFlight:
        waypoints = stored_waypoints(system, track, indices, options, set_down)
        return model_flight(system, track, waypoints, validity, landing, options, settings, flights)

    for _ in range(MAX_SPLITS + 1):
        trial = attempt(indices)
        badness = trial.check.badness(options)
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
        trial = merge_early_legs(trial, attempt, options)
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
