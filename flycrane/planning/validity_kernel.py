"""Compiled validity of states and motions: bounds, statics (cost) and collisions in one pass.

A :class:`CompiledValidity` bundles what the kernels need (sampling bounds, the statics
model, the compiled scene, the metric's weights) as one tuple of arrays, so that a motion
check, or a planner's extension, is one compiled call with no Python per configuration.

Order of the checks per configuration: bounds (a few comparisons), statics (~1 us, and most
random configurations fail it), collisions (~1-3 us). Motions are discretized by the state
space's one discretization (:func:`flycrane.planning.interpolation.segment_count`) and their
configurations checked end first, then in bisection order (strides 2^k, 2^(k-1), ...): an
invalid stretch is found after a few checks wherever it lies, as OMPL's
DiscreteMotionValidator does.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from flycrane.kernels import kernel
from flycrane.model.cable_system import CableSystem
from flycrane.model.cost import CostForm
from flycrane.model.statics_kernel import statics_model, statics_row, statics_workspace
from flycrane.planning.interpolation import interpolate_into, segment_count
from flycrane.planning.state_space import ConfigurationSpace
from flycrane.world.collision_kernel import (
    CompiledScene,
    collision_free_posed,
    collision_free_row,
    kinematic_arrays,
)
from flycrane.world.scene import SceneSpec

#: Index in the workspace of the count of configurations checked (:meth:`CompiledValidity.
#: checked`).
CHECKED = 11


@kernel()
def in_bounds(q, bounds) -> bool:
    """q inside the sampling bounds: [low xyz, high xyz, max tilt, alpha range, sigma range]."""
    for a in range(3):
        if not bounds[a] <= q[a] <= bounds[3 + a]:
            return False
    if q[4] > bounds[6]:
        return False
    for k in range(6, 9):
        if not bounds[7] <= q[k] <= bounds[8]:
            return False
    span = bounds[10] - bounds[9]
    offset = (q[5] - bounds[9]) % (2.0 * math.pi)
    # 1e-12: the range's own end points must pass after wrapping round-off
    return offset <= span + 1e-12 or offset >= 2.0 * math.pi - 1e-12


@kernel()
def state_check(q, model, work, use_bounds) -> tuple[float, bool]:
    """(cost, valid) of one configuration; the cost is +inf outside the bounds (when used)
    and where infeasible, and valid means finite cost and no collision."""
    bounds, smodel, kin, scene, _ = model
    statics_work, f0, v, m, collision_work = work[0], work[1], work[2], work[3], work[4:11]
    work[CHECKED][0] += 1
    if use_bounds and not in_bounds(q, bounds):
        return math.inf, False
    cost = statics_row(q, smodel, f0, v, m, statics_work)
    if not cost < math.inf:
        return cost, False
    rot, offsets = statics_work[0], statics_work[5]  # q's pose, as the statics computed it
    return cost, collision_free_posed(q, rot, offsets, kin, scene, collision_work)


@kernel(inline="always")
def collisions_free(q, model, work) -> bool:
    """The rest of :func:`state_check` for a configuration already known to lie in bounds
    and to be feasible (a caller that ranks configurations by their statics first)."""
    work[CHECKED][0] += 1
    return collision_free_row(q, model[2], model[3], work[4:11])


@kernel()
def _states(q, model, work, use_bounds, cost, valid) -> None:
    for row in range(q.shape[0]):
        cost[row], valid[row] = state_check(q[row], model, work, use_bounds)


@kernel()
def motion_check(a, b, resolution, model, work, use_bounds, check_start, check_end) -> bool:
    """Whether every configuration of the discretized local path a -> b is valid (module
    docstring); a, the start, is checked only with ``check_start`` (tree nodes are valid),
    b only with ``check_end`` (a caller that has just checked b)."""
    weights = model[4]
    pieces = segment_count(a, b, resolution, weights[0], weights[1])
    q = work[-1][0]
    if check_start and not state_check(a, model, work, use_bounds)[1]:
        return False
    interpolate_into(a, b, 1.0, q)
    if check_end and not state_check(q, model, work, use_bounds)[1]:
        return False
    stride = 1
    while stride * 2 < pieces:
        stride *= 2
    while stride >= 1:
        for k in range(stride, pieces, 2 * stride):
            interpolate_into(a, b, k / pieces, q)
            if not state_check(q, model, work, use_bounds)[1]:
                return False
        stride //= 2
    return True


@kernel()
def motion_last_valid(a, b, resolution, model, work, use_bounds) -> float:
    """Fraction t of the local path a -> b up to which every discretized configuration is
    valid (a, a tree node, is taken as valid): 1.0 if all are, else the last valid one's."""
    weights = model[4]
    pieces = segment_count(a, b, resolution, weights[0], weights[1])
    q = work[-1][0]
    for k in range(1, pieces + 1):
        interpolate_into(a, b, k / pieces, q)
        if not state_check(q, model, work, use_bounds)[1]:
            return (k - 1) / pieces
    return 1.0


@kernel()
def _motions(a, b, resolution, model, work, use_bounds, out) -> None:
    for row in range(a.shape[0]):
        out[row] = motion_check(a[row], b[row], resolution, model, work, use_bounds, True, True)


@dataclass(frozen=True, eq=False)
class CompiledValidity:
    """The kernels' inputs for one system, scene and state space (module docstring)."""

    model: tuple
    compiled_scene: CompiledScene

    @classmethod
    def build(
        cls,
        system: CableSystem,
        scene: SceneSpec,
        space: ConfigurationSpace,
        base_dir: Path | None = None,
    ) -> CompiledValidity:
        bounds = np.array(
            [
                *space.position_low,
                *space.position_high,
                space.max_tilt,
                space.alpha_low,
                space.alpha_high,
                space.sigma_low,
                space.sigma_high,
            ]
        )
        kinematics = kinematic_arrays(system)
        compiled = CompiledScene.build(system, scene, base_dir)
        model = (
            bounds,
            statics_model(system, CostForm.NORMALIZED),
            kinematics,
            compiled.arrays,
            np.array([space.rotation_weight, space.alpha_weight]),
        )
        return cls(model, compiled)

    def workspace(self) -> tuple:
        """Scratch for one caller (kernels write into it; not shared between threads)."""
        return (
            statics_workspace(),
            np.empty(6),
            np.empty(6),
            np.empty(3),
            *self.compiled_scene.workspace(),
            np.zeros(1, dtype=np.int64),  # CHECKED
            np.empty((3, 18)),  # configurations, embeddings, repair gradients
        )

    @staticmethod
    def checked(work: tuple) -> int:
        """Configurations checked with ``work`` since it was made: what a planner's time
        mostly goes to (``benchmarks/attempt_cost.py``)."""
        return int(work[CHECKED][0])

    def states(self, q: np.ndarray, use_bounds: bool, work: tuple) -> tuple[np.ndarray, np.ndarray]:
        """(cost (N,), valid (N,)) of configurations (N, 9); collisions with payload meshes
        are not checked here (:attr:`CompiledScene.payload_meshes`)."""
        cost, valid = np.empty(len(q)), np.empty(len(q), dtype=np.bool_)
        _states(q, self.model, work, use_bounds, cost, valid)
        return cost, valid

    def motion(
        self, a: np.ndarray, b: np.ndarray, resolution: float, work: tuple, use_bounds: bool = True
    ) -> bool:
        return bool(motion_check(a, b, resolution, self.model, work, use_bounds, False, True))

    def motions(
        self, a: np.ndarray, b: np.ndarray, resolution: float, work: tuple, use_bounds: bool = True
    ) -> np.ndarray:
        out = np.empty(len(a), dtype=np.bool_)
        _motions(a, b, resolution, self.model, work, use_bounds, out)
        return out
