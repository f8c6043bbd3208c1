"""How much timing error between the drones a mission tolerates (design.md section 9).

Timing, not geometry, is the weak link of waypoint missions for a cable-suspended load:
three autopilots start apart and stretch their legs differently (design.md section 9). So
for every mission set we compute, by bisection:

- **start offset**: the largest delay ``dt`` such that, whichever one or two drones start
  ``dt`` late (all six cases), the configuration reconstructed from the three drones'
  positions stays valid (feasible, collision-free) at every check time of the flight;
- **speed mismatch**: the largest ``eps`` such that any one drone flying all its legs at
  ``(1 + eps)`` or ``(1 - eps)`` times the planned speed keeps the load valid.

Each drone flies the motion the autopilot model predicts for it (:class:`FlightPlan`) on its
own warped clock: late drones wait at their start, drones that finish early hold their last
waypoint. The bisection assumes a larger error is never safer, and stops at
``TOLERANCE_RESOLUTION``; only the least limit over the cases is searched to that resolution.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from itertools import combinations

import numpy as np
from numpy.typing import NDArray

from flycrane.model.cable_system import CableSystem
from flycrane.model.direct_kinematics_kernel import compiled_direct_kinematics
from missions.options import MissionOptions
from missions.trajectory.flight_plan import FlightPlan
from missions.trajectory.tracks import Track
from missions.trajectory.waypoints import SafetyCheck, planned_configurations

#: Bisection stops when the bracket is this small, relative to its search range.
TOLERANCE_RESOLUTION = 1e-3
#: Load checks per ``check_resolution`` (a faster drone on a spline chain brought the load
#: out of its limits for less than 0.1 s, between two checks a step apart).
SAMPLES_PER_STEP = 4


@dataclass(frozen=True)
class TimingTolerance:
    """Largest tolerated start offset [s] and speed mismatch [fraction], with worst cases."""

    start_offset: float
    start_offset_case: str  #: which drones late, at the limit
    speed_mismatch: float
    speed_mismatch_case: str  #: which drone, faster or slower, at the limit
    searched_offset: float  #: the offset search range [s]
    searched_mismatch: float  #: the mismatch search range

    def as_dict(self) -> dict:
        return dict(self.__dict__)


def flight_is_safe(
    system: CableSystem,
    track: Track,
    plan: FlightPlan,
    validity: SafetyCheck,
    clock: Callable[[NDArray], NDArray],
    step: float,
) -> bool:
    """Whether drones flying the plan on warped clocks keep the load valid throughout.

    ``clock(t)`` maps mission time t (C,) to each drone's own mission time, shape (C, 3).
    The load is checked :data:`SAMPLES_PER_STEP` times per ``step``, until the last drone's
    clock reaches the end.
    """
    end = plan.duration
    coarse = np.arange(0.0, 2.0 * end + step, step)
    finished = np.flatnonzero(clock(coarse).min(axis=1) >= end)
    horizon = coarse[finished[0]] if len(finished) else coarse[-1]
    t = np.arange(0.0, horizon + step, step / SAMPLES_PER_STEP)
    local = clock(t)
    drones = plan.motion.at_each(local)
    # Start the reconstruction from the plan at the drones' mean progress.
    initial = planned_configurations(track, plan.progress_time(np.clip(local.mean(axis=1), 0, end)))
    rebuilt = compiled_direct_kinematics(system, drones, initial)
    return bool(np.all(rebuilt.converged & validity(rebuilt.q)))


def _least_largest_safe(
    cases: Sequence[tuple[str, Callable[[float], bool]]], limit: float
) -> tuple[float, str]:
    """The least over cases of the largest x in [0, limit] each case is safe at, and the case
    that sets it (the first case when every one is safe at ``limit``).

    Only the minimum is reported, so a case safe at the minimum found so far cannot lower it
    and costs one check; a case unsafe there is bisected below it. With the cases' limits
    close together that is about one bisection in all instead of one per case.
    """
    least, least_case = limit, cases[0][0]
    for case, safe in cases:
        if safe(least):
            continue
        low, high = 0.0, least
        while high - low > TOLERANCE_RESOLUTION * limit:
            mid = (low + high) / 2
            low, high = (mid, high) if safe(mid) else (low, mid)
        least, least_case = low, case
    return least, least_case


def timing_tolerance(
    system: CableSystem,
    track: Track,
    plan: FlightPlan,
    validity: SafetyCheck,
    options: MissionOptions,
    max_offset: float = 5.0,
    max_mismatch: float = 0.5,
) -> TimingTolerance:
    """Timing tolerance of a waypoint plan (module docstring)."""
    step = options.check_resolution

    def safe(clock: Callable[[NDArray], NDArray]) -> bool:
        return flight_is_safe(system, track, plan, validity, clock, step)

    offsets = []
    for late in [c for n in (1, 2) for c in combinations(range(3), n)]:
        mask = np.isin(np.arange(3), late)

        def late_by(d: float, mask: NDArray[np.bool_] = mask) -> bool:
            return safe(lambda t: t[:, None] - d * mask)

        offsets.append(("drones " + " and ".join(str(j + 1) for j in late) + " late", late_by))
    mismatches = []
    for j in range(3):
        for sign, word in ((1.0, "faster"), (-1.0, "slower")):
            mask = np.arange(3) == j

            def off_by(e: float, mask: NDArray[np.bool_] = mask, sign: float = sign) -> bool:
                return safe(lambda t: t[:, None] * (1 + sign * e * mask))

            mismatches.append((f"drone {j + 1} {word}", off_by))
    offset, offset_case = _least_largest_safe(offsets, max_offset)
    mismatch, mismatch_case = _least_largest_safe(mismatches, max_mismatch)
    return TimingTolerance(offset, offset_case, mismatch, mismatch_case, max_offset, max_mismatch)
