"""The bidirectional T-RRT's main loop, compiled: no Python per expansion attempt.

:class:`flycrane.planning.algorithms.bitrrt.BiTRRT` describes the algorithm; this module runs it.
The two trees live in arrays with a leading tree axis (:class:`Forest`), and :func:`run` does
``iterations`` expansion attempts in one compiled call, returning to Python only to check the
termination condition, report progress, or enlarge the arrays. Random numbers come from the solve's
own numpy Generator (numba draws from it and leaves its state advanced), so a seed gives one tree
whatever the batching and whatever else the thread runs.

Per attempt (tree ``t`` grows, ``o`` is the other; the shares are :class:`Params`):

1. Target: a local sample around a random node of the other tree (``other_share``), of
   tree t (``local_share``), or a uniform sample of the bounds.
2. The nearest node of t; the target keeps only its position (``translate_share``) or only
   its orientation and formation (``rotate_share``), the rest from the nearest node.
3. Extend (:func:`~flycrane.planning.algorithms.extension_kernel.extend`, the alphas repaired with
   probability ``repair_share``); a blocked motion tries reshape-first, then the part of
   the motion that is valid (``partial``); transition test, frontier control, add.
4. Connect tree o towards the new node, step by step, each step transition-tested.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numba
import numpy as np

from flycrane.kernels import kernel
from flycrane.planning.algorithms.extension_kernel import (
    ADVANCED,
    BLOCKED,
    FAILED,
    NO_REPAIR,
    REACHED,
    REPAIR,
    REPAIR_UNLESS_REACHED,
    advance_partial,
    embed_into,
    extend,
    reshape_first,
)
from flycrane.planning.algorithms.neighbours import EMBEDDING, TABLE_SIZE, grid_insert, grid_nearest
from flycrane.planning.interpolation import angles_into, quaternion, wrap

#: run()'s outcomes: the batch of attempts is done; the trees met (``meet`` holds the two
#: node indices); the arrays are nearly full (enlarge them and call again).
RUNNING, MET, FULL = 0, 1, 2
#: Steps of one connection at most: each moves a step, or at least ``partial``, towards
#: its target, but the alpha repair can move it away again (the alphas go down the cost,
#: not towards the target's), so the loop is bounded rather than trusted to converge.
CONNECT_STEPS = 100
#: Nodes one attempt can add at most (an extension and a connection, each step with a
#: reshape-first node), with room to spare: the arrays are never written past their end.
MARGIN = 2 * (CONNECT_STEPS + 1) + 16

#: Indices of the counters array.
(
    ATTEMPTS,
    INVALID,
    TRANSITION,
    REFINEMENT,
    REFINING,
    FRONTIER,
    RESHAPED,
    PARTIAL,
    CURRENT,
    N_COUNTERS,
) = range(10)
#: Indices of a tree's scalars: lowest and highest node cost, temperature.
LOW, HIGH, TEMPERATURE = range(3)


@dataclass(frozen=True)
class Params:
    """The loop's numbers (see :class:`~flycrane.planning.algorithms.bitrrt.BiTRRTConfig`)."""

    step: float
    connection_range: float
    frontier_threshold: float
    frontier_ratio: float
    temperature_rate: float
    cost_range_fraction: float
    cost_threshold: float
    free_level: float
    log_cost: float
    repair_share: float
    translate_share: float
    rotate_share: float
    local_share: float
    other_share: float
    local_radius: float
    partial: float
    reshape_first: float
    resolution: float
    #: the repair's objective: caps on eq. 8's slack, overload and thrust factors and the
    #: capped term's weight (:func:`~.extension_kernel.repair_objective`)
    cap_slack: float
    cap_overload: float
    cap_thrust: float
    margin_weight: float

    def array(self) -> np.ndarray:
        return np.array([getattr(self, name) for name in self.__dataclass_fields__])


(
    P_STEP,
    P_CONNECTION_RANGE,
    P_FRONTIER_THRESHOLD,
    P_FRONTIER_RATIO,
    P_TEMPERATURE_RATE,
    P_COST_RANGE_FRACTION,
    P_COST_THRESHOLD,
    P_FREE_LEVEL,
    P_LOG_COST,
    P_REPAIR_SHARE,
    P_TRANSLATE_SHARE,
    P_ROTATE_SHARE,
    P_LOCAL_SHARE,
    P_OTHER_SHARE,
    P_LOCAL_RADIUS,
    P_PARTIAL,
    P_RESHAPE_FIRST,
    P_RESOLUTION,
    P_CAP_SLACK,
    P_CAP_OVERLOAD,
    P_CAP_THRUST,
    P_MARGIN_WEIGHT,
) = range(22)


class Forest:
    """The two trees' arrays (tree axis first) and their grid indices."""

    def __init__(self, capacity: int, cell: float) -> None:
        self.cell = cell
        self.q = np.empty((2, capacity, 9))
        self.embedding = np.empty((2, capacity, EMBEDDING))
        self.parent = np.empty((2, capacity), dtype=np.int64)
        self.cost = np.empty((2, capacity))
        self.head = np.full((2, TABLE_SIZE), -1, dtype=np.int64)
        self.chain = np.empty((2, capacity), dtype=np.int64)
        self.cells = np.empty((2, capacity, 3), dtype=np.int64)
        self.size = np.zeros(2, dtype=np.int64)
        self.scalars = np.empty((2, 3))

    @property
    def capacity(self) -> int:
        return self.q.shape[1]

    def enlarge(self) -> None:
        """Double the capacity, keeping every node (the grid's chains index nodes)."""
        for name in ("q", "embedding", "parent", "cost", "chain", "cells"):
            old = getattr(self, name)
            new = np.empty((2, 2 * old.shape[1], *old.shape[2:]), dtype=old.dtype)
            new[:, : old.shape[1]] = old
            setattr(self, name, new)

    def arrays(self) -> tuple:
        return (
            self.q,
            self.embedding,
            self.parent,
            self.cost,
            self.head,
            self.chain,
            self.cells,
            self.size,
            self.scalars,
            self.cell,
        )


@kernel()
def add_node(forest, t, q, parent, cost, weights) -> int:
    """Append a node to tree t; its index."""
    qs, emb, parents, costs, head, chain, cells, size, scalars, cell = forest
    index = size[t]
    for k in range(9):
        qs[t, index, k] = q[k]
    embed_into(qs[t, index], weights, emb[t, index])
    parents[t, index] = parent
    costs[t, index] = cost
    grid_insert(head[t], chain[t], cells[t], index, emb[t, index], cell)
    if index == 0:
        scalars[t, LOW] = scalars[t, HIGH] = cost
    else:
        scalars[t, LOW] = min(scalars[t, LOW], cost)
        scalars[t, HIGH] = max(scalars[t, HIGH], cost)
    size[t] = index + 1
    return index


@kernel()
def _nearest(forest, t, point) -> tuple[int, float]:
    _, emb, _, _, head, chain, cells, size, _, cell = forest
    return grid_nearest(head[t], chain[t], cells[t], emb[t], size[t], point, cell)


@kernel()
def sample_uniform(rng, bounds, out) -> None:
    """A configuration uniform in the bounds (ConfigurationSpace.sample_uniform's law)."""
    for a in range(3):
        out[a] = rng.uniform(bounds[a], bounds[3 + a])
    out[3] = rng.uniform(-math.pi, math.pi)
    out[4] = math.acos(rng.uniform(math.cos(bounds[6]), 1.0))
    out[5] = wrap(rng.uniform(bounds[9], bounds[10]))
    for k in range(6, 9):
        out[k] = rng.uniform(bounds[7], bounds[8])


@kernel()
def sample_near(rng, q, radius, bounds, weights, out) -> None:
    """A configuration about ``radius`` (metric units) from q: Gaussian position offsets, a
    Gaussian rotation vector (world axes) and Gaussian alpha offsets, each scaled by its
    lever arm so that every part moves about radius / sqrt(3); clipped into the bounds."""
    sigma = radius / math.sqrt(3.0)
    for a in range(3):
        out[a] = min(bounds[3 + a], max(bounds[a], q[a] + rng.normal(0.0, sigma)))
    rx = rng.normal(0.0, sigma / weights[0])
    ry = rng.normal(0.0, sigma / weights[0])
    rz = rng.normal(0.0, sigma / weights[0])
    angle = math.sqrt(rx * rx + ry * ry + rz * rz)
    aw, ax, ay, az = quaternion(q[3], q[4], q[5])
    half = 0.5 * angle
    s = math.sin(half) / angle if angle > 1e-12 else 0.5
    w, x, y, z = math.cos(half), s * rx, s * ry, s * rz
    # (w, x, y, z) * (aw, ax, ay, az): the offset rotation applied in world axes
    angles_into(
        w * aw - x * ax - y * ay - z * az,
        w * ax + x * aw + y * az - z * ay,
        w * ay - x * az + y * aw + z * ax,
        w * az + x * ay - y * ax + z * aw,
        out,
        3,
    )
    out[4] = min(out[4], bounds[6])
    for k in range(6, 9):
        out[k] = min(bounds[8], max(bounds[7], q[k] + rng.normal(0.0, sigma / weights[1])))


@kernel()
def _energy(cost, log_cost) -> float:
    return math.log(cost) if log_cost else cost


@kernel()
def accepts(scalars, t, c_from, c_to, params, counters) -> bool:
    """transitionTest (OMPL BiTRRT) in tree t's direction of growth, on log c or c."""
    if c_to > params[P_COST_THRESHOLD]:
        return False
    if c_to <= params[P_FREE_LEVEL]:
        return True
    log_cost = params[P_LOG_COST] > 0.0
    climb = _energy(c_to, log_cost) - _energy(c_from, log_cost)
    if climb <= 0.0:
        return True
    if climb < scalars[t, TEMPERATURE] * math.log(2.0):  # exp(-climb / T) > 0.5
        spread = _energy(scalars[t, HIGH], log_cost) - _energy(scalars[t, LOW], log_cost)
        if spread > 0.0:
            cooling = climb / (params[P_COST_RANGE_FRACTION] * spread)
            scalars[t, TEMPERATURE] /= math.exp(min(cooling, 700.0))
        return True
    scalars[t, TEMPERATURE] *= math.exp(params[P_TEMPERATURE_RATE])
    counters[TRANSITION] += 1
    return False


@kernel()
def _frontier_allows(distance, params, counters) -> bool:
    """minExpansionControl (OMPL BiTRRT)."""
    if distance > params[P_FRONTIER_THRESHOLD]:
        counters[FRONTIER] += 1
        return True
    if counters[REFINING] / counters[FRONTIER] > params[P_FRONTIER_RATIO]:
        counters[REFINEMENT] += 1
        return False
    counters[REFINING] += 1
    return True


@kernel()
def grow(forest, t, near, target, repair, params, model, work, counters, out) -> tuple[int, int]:
    """One extension of tree t from node ``near`` towards ``target``: (outcome, new index
    or -1)."""
    qs, emb, _, costs, _, _, _, _, scalars, _ = forest
    weights, resolution = model[4], params[P_RESOLUTION]
    outcome, cost = extend(
        qs[t, near], target, params[P_STEP], repair, params[P_PARTIAL], resolution, model, work,
        out, params[P_CAP_SLACK : P_MARGIN_WEIGHT + 1],
    )  # fmt: skip
    if outcome == BLOCKED and params[P_RESHAPE_FIRST] > 0.0:
        middle = work[-1][2, 9:]  # free again after extend
        middle_cost = reshape_first(qs[t, near], out, resolution, model, work, middle)
        if middle_cost < math.inf and accepts(
            scalars, t, costs[t, near], middle_cost, params, counters
        ):
            counters[RESHAPED] += 1
            near = add_node(forest, t, middle, near, middle_cost, weights)
            outcome = ADVANCED
    if outcome == BLOCKED and params[P_PARTIAL] > 0.0:
        cost = advance_partial(qs[t, near], out, params[P_PARTIAL], resolution, model, work)
        if cost < math.inf:
            counters[PARTIAL] += 1
            outcome = ADVANCED
    if outcome == FAILED or outcome == BLOCKED:
        counters[INVALID] += 1
        return FAILED, -1
    point = work[-1][1, :EMBEDDING]
    embed_into(out, weights, point)
    distance = 0.0
    for a in range(EMBEDDING):
        distance += (emb[t, near, a] - point[a]) ** 2
    if not accepts(scalars, t, costs[t, near], cost, params, counters):
        return FAILED, -1
    if not _frontier_allows(math.sqrt(distance), params, counters):
        return FAILED, -1
    return outcome, add_node(forest, t, out, near, cost, weights)


@kernel()
def connect(forest, t, target, near, distance, params, model, work, counters, out) -> int:
    """Grow tree t towards ``target``, from its nearest node ``near`` at ``distance``, until
    it reaches it (the node's index) or not (-1)."""
    if distance > params[P_CONNECTION_RANGE]:
        return -1
    for _ in range(CONNECT_STEPS):
        outcome, index = grow(
            forest, t, near, target, REPAIR_UNLESS_REACHED, params, model, work, counters, out
        )
        if outcome == FAILED:
            return -1
        if outcome == REACHED:
            return index
        near = index
    return -1


@numba.njit(cache=True, nogil=True)
def run(forest, rng, params, model, work, counters, gap, meet, iterations) -> int:
    """Up to ``iterations`` expansion attempts (module docstring); RUNNING, MET or FULL."""
    qs, emb, _, _, _, _, _, size, _, _ = forest
    bounds, weights = model[0], model[4]
    target, out, new, point = np.empty(9), np.empty(9), np.empty(9), np.empty(EMBEDDING)
    capacity = qs.shape[1]
    for _ in range(iterations):
        if size[0] + MARGIN > capacity or size[1] + MARGIN > capacity:
            return FULL
        counters[ATTEMPTS] += 1
        t = counters[CURRENT]
        o = 1 - t
        u = rng.random()
        if u < params[P_OTHER_SHARE]:
            node = rng.integers(0, size[o])
            sample_near(rng, qs[o, node], params[P_LOCAL_RADIUS], bounds, weights, target)
        elif u < params[P_OTHER_SHARE] + params[P_LOCAL_SHARE]:
            node = rng.integers(0, size[t])
            sample_near(rng, qs[t, node], params[P_LOCAL_RADIUS], bounds, weights, target)
        else:
            sample_uniform(rng, bounds, target)
        embed_into(target, weights, point)
        near, _ = _nearest(forest, t, point)
        mode = rng.random()
        if mode < params[P_TRANSLATE_SHARE]:
            for k in range(3, 9):
                target[k] = qs[t, near, k]
        elif mode < params[P_TRANSLATE_SHARE] + params[P_ROTATE_SHARE]:
            for k in range(3):
                target[k] = qs[t, near, k]
        repair = REPAIR if rng.random() < params[P_REPAIR_SHARE] else NO_REPAIR
        outcome, index = grow(forest, t, near, target, repair, params, model, work, counters, out)
        if outcome != FAILED:
            near, distance = _nearest(forest, o, emb[t, index])
            gap[0] = min(gap[0], distance)
            new[:] = qs[t, index]
            met = connect(forest, o, new, near, distance, params, model, work, counters, out)
            if met >= 0:
                meet[t], meet[o] = index, met
                return MET
        counters[CURRENT] = o
    return RUNNING
