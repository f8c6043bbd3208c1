"""The planner's validity checker: sampling bounds, statics feasibility and collisions.

OMPL's StateValidityChecker and MotionValidator roles for the FlyCrane. A configuration is
valid when it lies in the scene's sampling bounds, its cost is finite (wrench- and
thrust-feasible, J non-singular) and no body collides. Every check runs in compiled code
(:mod:`flycrane.planning.validity_kernel`): bounds, then statics (~1 us), then collisions
of the primitive shapes (:mod:`flycrane.world.collision_kernel`, ~1-3 us). python-fcl
(:class:`~flycrane.world.collision.CollisionChecker`) remains the reference the kernel is tested
against, the checker of payload meshes (configurations the kernel finds free with a
payload mesh are checked by fcl as well), and the source of contact depths and clearances
in messages.

Motions are checked along the local path at ``resolution`` (default 0.05 of path length,
:meth:`ConfigurationSpace.discretize`: about 5 cm of drone travel, against 0.3 m drone
spheres and obstacles at least centimetres thick), both end points included.

Not thread-safe: each checker owns the kernels' scratch; worker processes and threads build
their own (pickling rebuilds it).
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike, NDArray

from flycrane.errors import FlyCraneError
from flycrane.model.cable_system import CableSystem
from flycrane.model.feasibility import Violation, violations
from flycrane.model.kinematics import COORDINATES, as_configurations
from flycrane.model.statics import evaluate_statics
from flycrane.model.statics_kernel import configuration_cost
from flycrane.planning.state_space import ConfigurationSpace
from flycrane.planning.validity_kernel import CompiledValidity
from flycrane.world.collision import CollisionChecker
from flycrane.world.contact import Contact
from flycrane.world.scene import SceneSpec

#: Default motion-check step [state-space distance] (module docstring).
MOTION_RESOLUTION = 0.05


@dataclass(frozen=True)
class InvalidReason:
    """Why one configuration is invalid: bounds, statics and contacts, all of them."""

    out_of_bounds: tuple[str, ...] = ()
    violations: tuple[Violation, ...] = ()
    contacts: tuple[Contact, ...] = field(default_factory=tuple)

    @property
    def valid(self) -> bool:
        return not (self.out_of_bounds or self.violations or self.contacts)

    def __str__(self) -> str:
        parts = [f"outside the bounds: {b}" for b in self.out_of_bounds]
        parts += [str(v) for v in self.violations]
        parts += [str(c) for c in self.contacts]
        return "; ".join(parts) or "valid"


class InvalidConfigurationError(FlyCraneError):
    """A configuration that must be valid (``what``: "start", "goal", ...) is not."""

    def __init__(self, what: str, reason: InvalidReason) -> None:
        self.what, self.reason = what, reason
        super().__init__(f"{what} is invalid: {reason}")


class ValidityChecker:
    """Validity and cost of configurations of one system in one scene."""

    def __init__(
        self,
        system: CableSystem,
        scene: SceneSpec,
        space: ConfigurationSpace,
        base_dir: Path | None = None,
        resolution: float = MOTION_RESOLUTION,
    ) -> None:
        self.system, self.scene, self.space, self.base_dir = system, scene, space, base_dir
        self.resolution = resolution
        self.collision = CollisionChecker(system, scene, base_dir)
        self.compiled = CompiledValidity.build(system, scene, space, base_dir)
        self.work = self.compiled.workspace()
        self.payload_meshes = self.compiled.compiled_scene.payload_meshes

    def __reduce__(self):
        # fcl objects do not pickle; worker processes rebuild the checker (milliseconds).
        return (
            ValidityChecker,
            (self.system, self.scene, self.space, self.base_dir, self.resolution),
        )

    def with_clearance(self, clearance: float) -> ValidityChecker:
        """The same checker with another ``obstacle_clearance`` [m] (0: the real obstacles);
        itself if the clearance is the same (building one costs the fcl objects)."""
        if clearance == self.scene.collision.obstacle_clearance:
            return self
        collision = self.scene.collision.model_copy(update={"obstacle_clearance": clearance})
        scene = self.scene.model_copy(update={"collision": collision})
        return ValidityChecker(self.system, scene, self.space, self.base_dir, self.resolution)

    def without(self, names: Iterable[str]) -> ValidityChecker:
        """The same checker without the named obstacles (``"ground"``: the ground), e.g.
        the surfaces a set-down is meant to touch."""
        names = tuple(names)
        if not names:
            return self
        return ValidityChecker(
            self.system, self.scene.without(names), self.space, self.base_dir, self.resolution
        )

    def _states(self, q: ArrayLike, use_bounds: bool) -> tuple[NDArray, NDArray]:
        q = np.ascontiguousarray(as_configurations(q))
        cost, valid = self.compiled.states(q, use_bounds, self.work)
        if self.payload_meshes and valid.any():
            valid[valid] = self.collision.collision_free(q[valid])
        return cost, valid

    def cost(self, q: ArrayLike) -> NDArray[np.float64]:
        """c(q) per configuration, +inf where infeasible or outside the bounds (N,)."""
        q = as_configurations(q)
        cost = configuration_cost(self.system, q)
        cost[~self.space.contains(q)] = np.inf
        return cost

    def is_valid(self, q: ArrayLike) -> NDArray[np.bool_]:
        """In bounds, feasible and collision-free, per configuration (N,)."""
        return self._states(q, use_bounds=True)[1]

    def cost_and_validity(self, q: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.bool_]]:
        """(cost (N,), valid (N,)) in one pass: the cost is :meth:`cost`'s."""
        return self._states(q, use_bounds=True)

    def is_safe(self, q: ArrayLike) -> NDArray[np.bool_]:
        """Feasible and collision-free, ignoring the sampling bounds (N,): what a flown
        configuration must be (the bounds only shape where the planner searches)."""
        return self._states(q, use_bounds=False)[1]

    def motion_is_valid(self, q_from: ArrayLike, q_to: ArrayLike) -> bool:
        """Every configuration of the local path q_from -> q_to is valid, both ends
        included."""
        a = np.ascontiguousarray(q_from, dtype=float).reshape(9)
        b = np.ascontiguousarray(q_to, dtype=float).reshape(9)
        if self.payload_meshes:
            return bool(self.is_valid(self.space.discretize(a, b, self.resolution)).all())
        return bool(self.is_valid(a[None])[0]) and self.compiled.motion(
            a, b, self.resolution, self.work
        )

    def motions_are_valid(self, q_from: ArrayLike, q_to: ArrayLike) -> NDArray[np.bool_]:
        """:meth:`motion_is_valid` of many motions (N, 9) -> (N,), in one compiled call."""
        a = np.ascontiguousarray(as_configurations(q_from, "q_from"))
        b = np.ascontiguousarray(as_configurations(q_to, "q_to"))
        if self.payload_meshes:
            return np.array([self.motion_is_valid(x, y) for x, y in zip(a, b, strict=True)])
        return self.compiled.motions(a, b, self.resolution, self.work)

    def explain(self, q: ArrayLike) -> InvalidReason:
        """Every reason why the configuration (9,) is invalid (empty if valid)."""
        q = as_configurations(q)[:1]
        space = self.space
        low, high = np.array(space.position_low), np.array(space.position_high)
        outside = [
            f"{COORDINATES[a]} = {q[0, a]:.4g} not in [{low[a]:.4g}, {high[a]:.4g}]"
            for a in range(3)
            if not low[a] <= q[0, a] <= high[a]
        ]
        if q[0, 4] > space.max_tilt:
            outside.append(f"theta = {q[0, 4]:.4g} above max_tilt {space.max_tilt:.4g}")
        if not space.sigma_in_range(q[0, 5]):
            outside.append(
                f"sigma = {q[0, 5]:.4g} not in [{space.sigma_low:.4g}, {space.sigma_high:.4g}]"
            )
        outside += [
            f"alpha{k + 1} = {q[0, 6 + k]:.4g} not in [{space.alpha_low:.4g}, "
            f"{space.alpha_high:.4g}]"
            for k in range(3)
            if not space.alpha_low <= q[0, 6 + k] <= space.alpha_high
        ]
        return InvalidReason(
            tuple(outside),
            tuple(violations(evaluate_statics(self.system, q))),
            tuple(self.collision.contacts(q[0])),
        )

    def describe_invalid(self, q: ArrayLike) -> str:
        return str(self.explain(q))

    def require_valid(self, q: ArrayLike, what: str) -> None:
        """Raise :class:`InvalidConfigurationError` naming every reason if q is invalid."""
        reason = self.explain(q)
        if not reason.valid:
            raise InvalidConfigurationError(what, reason)
