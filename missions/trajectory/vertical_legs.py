"""Lift-off and set-down: a start or goal that touches nothing but lies within the obstacle
clearance of a surface (the Rescue's footbridge 5 cm above the roofs, its start 5 cm above
the ground) is planned from or to the nearest raised pose that keeps the clearance.

- **Set-down**: the mission's last leg descends slowly from the raised goal to the goal
  (a spline leg timed at ``vertical_leg_speed``, the same on all three drones, ending at
  rest in the final hold). Contact with the named surfaces during it is its intended end
  (the load rests on the roof), not a failure; contact with anything else is. The raised
  goal is ``set_down_approach`` above the lowest clear pose: the path's last leg brakes
  there, and braking is where the drones err most, an error the hanging platform
  amplifies (BENCHMARKS.md, "Home height", "The set-down approach").
- **Lift-off**: the take-off climbs to the raised start with the load hanging below: it is
  the take-off that lifts the load from its surfaces, before the drones are released
  together (take-offs do not lift together, :mod:`missions.autopilots.ardupilot`, so the
  lift happens below the clearance, where the load was resting anyway).
- **The holds keep the bound.** The drones hold at a raised end for seconds, where a
  centimetre of their errors can tilt a long load by more (the hanging platform amplifies
  them): the raised pose is also high enough for the position-error model's bound on how
  far the platform and the payload may sink below it (:func:`hold_height`), where that
  stays clear.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from flycrane.model.pose_error import height_bound
from flycrane.planning.problem import PlanningProblem
from flycrane.planning.validity import InvalidConfigurationError, ValidityChecker
from flycrane.world.bodies import box_corners
from missions.position_error import PositionErrorModel

#: Raised poses are looked for up to this height above the given one, in this step [m].
MAX_RAISE = 1.0
RAISE_STEP = 0.01


@dataclass(frozen=True)
class VerticalLeg:
    """A slow vertical leg between ``low`` (touching ``surfaces`` within the clearance) and
    ``high`` (clear of everything by the clearance)."""

    low: NDArray[np.float64]  #: (9,) the start or goal as given
    high: NDArray[np.float64]  #: (9,) raised by :attr:`height`
    surfaces: tuple[str, ...]  #: obstacles (or "ground") ``low`` is within the clearance of

    @property
    def height(self) -> float:
        return float(self.high[2] - self.low[2])

    def as_dict(self) -> dict:
        return {
            "low": self.low.tolist(),
            "high": self.high.tolist(),
            "surfaces": list(self.surfaces),
            "height": self.height,
        }

    @classmethod
    def from_dict(cls, data: dict) -> VerticalLeg:
        """Inverse of :meth:`as_dict`."""
        return cls(
            np.array(data["low"], dtype=float),
            np.array(data["high"], dtype=float),
            tuple(data["surfaces"]),
        )


def hold_height(
    problem: PlanningProblem, model: PositionErrorModel, clearance: float
) -> Callable[[NDArray[np.float64]], float]:
    """How much higher [m] than the lowest pose that keeps ``clearance`` a hold at pose q
    must be: the bound of ``model``'s errors on how far the platform's and the payload's
    boxes may sink (:func:`~flycrane.model.pose_error.height_bound` at their corners, where
    a bound convex in the point is largest), less the clearance; 0 where that covers it.
    The bound does not change as the pose rises."""
    corners = np.concatenate([box_corners(b) for b in problem.validity.collision.platform_fixed])

    def needed(q: NDArray[np.float64]) -> float:
        bound = height_bound(problem.system, q, corners, model.common_vertical, model.own)
        return max(0.0, float(bound.max()) - clearance)

    return needed


def clear_end(
    q: NDArray[np.float64],
    validity: ValidityChecker,
    real: ValidityChecker,
    what: str,
    approach: float = 0.0,
    hold: Callable[[NDArray[np.float64]], float] | None = None,
) -> tuple[NDArray[np.float64], VerticalLeg | None]:
    """The pose to plan from or to for a start or goal ``q``, and its vertical leg if it
    needs one (module docstring): the lowest clear pose above ``q``, raised by up to
    ``approach`` [m] more, or what ``hold`` (:func:`hold_height`) says the hold needs if
    that is more, where that stays clear. ``validity`` keeps the plan's clearance,
    ``real`` is the same on the real obstacles.

    Raises
    ------
    InvalidConfigurationError
        If ``q`` is invalid on the real obstacles (statics, bounds, a contact), or no pose up
        to :data:`MAX_RAISE` above it keeps the clearance.
    """
    planning = validity.explain(q)
    if planning.valid:
        return q, None
    real.require_valid(q, what)
    if planning.out_of_bounds or planning.violations:
        raise InvalidConfigurationError(what, planning)
    surfaces = tuple(sorted({c.other for c in planning.contacts}))
    approach = max(approach, hold(q)) if hold else approach
    up = np.array([0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0])

    def clear(height: float) -> bool:
        high = q + height * up
        return bool(validity.is_valid(high)[0]) and _touches_only(real, q, high, surfaces)

    heights = np.arange(RAISE_STEP, MAX_RAISE + RAISE_STEP / 2, RAISE_STEP)
    lowest = next((float(h) for h in heights if clear(h)), None)
    if lowest is None:
        raise InvalidConfigurationError(what, planning)
    # the highest clear pose within the approach, looked for from the top
    extras = np.arange(approach, RAISE_STEP / 2, -RAISE_STEP)
    height = next((lowest + float(e) for e in extras if clear(lowest + e)), lowest)
    high = q + height * up
    return high, VerticalLeg(np.asarray(q, dtype=float), high, surfaces)


def _touches_only(
    real: ValidityChecker, low: NDArray, high: NDArray, surfaces: tuple[str, ...]
) -> bool:
    """Whether the vertical leg from ``low`` to ``high`` touches nothing but ``surfaces``."""
    steps = max(2, int(np.ceil(float(high[2] - low[2]) / RAISE_STEP)) + 1)
    for q in np.linspace(low, high, steps):
        reason = real.explain(q)
        if reason.violations or any(c.other not in surfaces for c in reason.contacts):
            return False
    return True
