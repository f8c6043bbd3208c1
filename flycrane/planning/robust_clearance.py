"""How far the drones' position errors can close a configuration's gap to the obstacles,
and a path's robust margin: its least gap less that bound.

The drones' errors move the platform through the direct kinematics
(:func:`flycrane.model.pose_error.pose_sensitivity`, G), and on near-vertical cables a few
centimetres of the drones' spread turn a long payload by far more in some poses than in
others: one fixed clearance is too small in some poses and wasted in others. With g the
gradient of the gap to the nearest obstacle in the platform's twist (from fcl's nearest
points, :meth:`~flycrane.world.collision.CollisionChecker.gap_gradients`) and n its
translation part, errors within ``common`` (c_h, c_v; shared by the three drones) and
``own`` (h, v; each drone's about their mean) close the gap by at most

    |n_xy| c_h + |n_z| c_v + sum_k (||(g G)_k[:2]|| h + |(g G)_k[2]| v)

to first order: the common error moves everything as one, each drone's own error moves
the platform through its three columns of G. The three drones' worst errors add, in the
same direction: the bound is conservative, by 2-4x against the gaps lost in ArduCopter
SITL flights (BENCHMARKS.md, "Robust margins along the nearest obstacle's direction"),
and it covered every one of them. Only configurations within ``near`` of an obstacle are
bounded: the gradient of a gap farther away says nothing about a contact.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from flycrane.model.kinematics import as_configurations, forward_kinematics
from flycrane.model.pose_error import pose_sensitivity
from flycrane.planning.state_space import ConfigurationSpace
from flycrane.planning.validity import ValidityChecker


class RobustClearance:
    """Gaps to the real obstacles and the bound of the drones' errors on closing them
    (module docstring); ``real`` checks the real obstacles (no clearance)."""

    def __init__(
        self,
        real: ValidityChecker,
        common: tuple[float, float],
        own: tuple[float, float],
        near: float = 0.25,
        resolution: float = 0.05,
    ) -> None:
        self.real, self.common, self.own = real, common, own
        self.near, self.resolution = near, resolution
        self._reach: ValidityChecker | None = None  #: the obstacles grown by ``near``

    def gaps(self, q: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """(gap [m] to the nearest real obstacle or the ground, bound [m] on how much of it
        the drones' errors can close; 0 farther than ``near``), per configuration (N,)."""
        q = as_configurations(q)
        gap, gradient = self.real.collision.gap_gradients(q)
        bound = np.zeros(len(q))
        rows = np.flatnonzero(gap <= self.near)
        if not len(rows):
            return gap, bound
        gradient = gradient[rows]  # (R, 6)
        g = pose_sensitivity(forward_kinematics(self.real.system, q[rows]))  # (R, 6, 9)
        per_drone = np.einsum("ra,rab->rb", gradient, g).reshape(-1, 3, 3)
        (c_h, c_v), (h, v) = self.common, self.own
        n = gradient[:, :3]
        own = np.linalg.norm(per_drone[..., :2], axis=-1) * h + np.abs(per_drone[..., 2]) * v
        bound[rows] = np.hypot(n[:, 0], n[:, 1]) * c_h + np.abs(n[:, 2]) * c_v + own.sum(axis=1)
        return gap, bound

    def margin(self, path: ArrayLike, space: ConfigurationSpace) -> float:
        """The path's robust margin [m]: its least gap less the bound there, over its
        samples ``resolution`` apart within ``near`` of an obstacle (+inf if none is)."""
        return self.samples_margin(space.discretize_path(as_configurations(path), self.resolution))

    def samples_margin(self, q: ArrayLike) -> float:
        """The least gap less the bound over configurations (N, 9) within ``near`` of an
        obstacle (+inf if none is). Those safe with the obstacles grown by ``near`` (the
        compiled checker, cheap) are not measured."""
        q = as_configurations(q)
        if self._reach is None:
            self._reach = self.real.with_clearance(self.near)
        q = q[~self._reach.is_safe(q)]
        gap, bound = self.gaps(q)
        close = gap <= self.near
        return float((gap[close] - bound[close]).min()) if close.any() else float("inf")
