"""Bidirectional T-RRT with formation repair: the planner for users' scenes (``bitrrt``).

Devaurs, Siméon, Cortés, "Enhancing the transition-based RRT to deal with complex cost
spaces", ICRA 2013 (T-RRT-Connect), as OMPL's ``BiTRRT`` (src/ompl/geometric/planners/rrt/
src/BiTRRT.cpp) implements it, with the FlyCrane's redundancy used at every extension.

Each iteration: sample q_rand; extend the current tree from its nearest node by at most
the step (:func:`flycrane.planning.extension_kernel.extend`: one compiled call that steps,
repairs the alphas and checks the motion); keep the node if the transition test accepts
the cost change and the frontier control allows it; then extend the other tree towards the
new node step by step (each step transition-tested) until it reaches it, fails, or is more
than ``connection_range`` away; swap the trees. A path exists when the trees meet.

As OMPL: the transition test sees the cost change in each tree's own direction of growth
(the goal tree grows away from the goal, so it too climbs out of the goal's basin only
when the temperature allows), cools by ``exp(dc / (0.1 costRange))`` after an accepted climb
and heats by ``exp(T_rate)`` after a refused one; the frontier control refuses refining
extensions (shorter than ``frontier_threshold``) beyond ``frontier_ratio`` of the
exploring ones. As the paper (Devaurs et al.), each tree keeps its own temperature, so a
tree stuck behind a climb does not cool the other.

FlyCrane-specific, each kept because it measured better (BENCHMARKS.md, "Planner v2",
"What each FlyCrane-specific choice buys"):

- Alpha repair (``repair_alphas``): the alphas of every new node are moved towards the least
  collision-free cost from the near node's alphas (a bounded descent on log c). The sampled
  alphas mean nothing; without repair, an extension towards a sample in a passage moves
  the formation towards the sample's arbitrary alphas, most such moves are steep climbs,
  and the transition test keeps the trees out (BENCHMARKS.md, "Puzzle": "only 4.6 % of
  samples have all three alphas in the low-cost band").
- Transition test on log c (``log_cost``): the normalized cost spans 1e7-1e11 along one
  path, so a climb worth accepting in a valley (x2) and one out of a cliff (x2) differ by
  orders of magnitude in c and not at all in log c.
- Narrow-passage sampling (``sampler``, :mod:`flycrane.planning.samplers`): available,
  not yet measured against uniform, so ``uniform`` is the default.

Both trees start at the task's start and goal; a path always ends exactly at the goal.
"""

from __future__ import annotations

import logging
import math
import time
from collections.abc import Callable
from dataclasses import dataclass, replace
from typing import Literal

import numpy as np
from numpy.typing import NDArray

from flycrane.errors import FieldProblem, InputError
from flycrane.planning.extension_kernel import (
    ADVANCED,
    BLOCKED,
    EMBEDDING,
    FAILED,
    NO_REPAIR,
    REACHED,
    REPAIR,
    REPAIR_UNLESS_REACHED,
    embed_into,
    extend,
    nearest,
    reshape_first,
)
from flycrane.planning.interfaces import CompiledChecker
from flycrane.planning.local_prototype import perturb_into
from flycrane.planning.result import (
    PlannerResult,
    PlannerStatistics,
    PlannerStatus,
    PlanningProgress,
    TerminationCondition,
)
from flycrane.planning.samplers import Sampler, make_sampler
from flycrane.planning.state_space import ConfigurationSpace
from flycrane.planning.tree import path_from_root

logger = logging.getLogger(__name__)

SamplerName = Literal["uniform", "gaussian", "bridge"]


@dataclass(frozen=True)
class BiTRRTConfig:
    """Parameters of the bidirectional T-RRT; None means "from the problem at setup"."""

    step: float | None = None  #: largest extension; None: STEP_FRACTION x the space's extent
    repair_alphas: bool = True
    #: share of the extensions towards samples that repair (the others keep the sample's
    #: alphas: the formation must also explore, e.g. narrow before a corridor)
    repair_share: float = 0.5
    #: share of the extensions that move the near node's position only (towards the
    #: sample's), keeping its orientation and formation: through a passage that fits one
    #: attitude, the attitude that got in gets through
    translate_share: float = 0.3
    #: where the straight motion to a valid new node fails, try reshaping the formation in
    #: place first (:func:`~flycrane.planning.extension_kernel.reshape_first`)
    reshape_first: bool = True
    log_cost: bool = True  #: transition test on log c instead of c
    #: accept without a test every move to a cost at most the start's or goal's (module
    #: docstring); False: T-RRT's test on every climb
    free_below_endpoints: bool = True
    sampler: SamplerName = "uniform"
    local_share: float = 0.0
    local_radius: float = 0.5
    balance: bool = False
    rotate_share: float = 0.0
    other_share: float = 0.0
    partial: float = 0.0
    cell_select: bool = False
    cell_size: float = 0.25
    adaptive_radius: bool = False
    init_temperature: float | None = None  #: None: 0.1 (log c) or 1e-6 c(root) (c)
    temperature_rate: float = 0.1  #: T *= exp(T_rate) after a refused climb (OMPL)
    cost_range_fraction: float = 0.1
    frontier_threshold: float | None = None  #: None: 0.01 x extent (OMPL)
    frontier_ratio: float = 0.1  #: refining / exploring extensions allowed (OMPL)
    connection_range: float | None = None  #: None: 10 x step
    cost_threshold: float = math.inf  #: c_max
    progress_interval: float = 0.5

    def __post_init__(self) -> None:
        checks = [
            ("step", self.step is None or self.step > 0, "must be > 0"),
            (
                "init_temperature",
                self.init_temperature is None or self.init_temperature > 0,
                "must be > 0",
            ),
            ("temperature_rate", 0.0 <= self.temperature_rate <= 1.0, "must be in [0, 1]"),
            ("cost_range_fraction", self.cost_range_fraction > 0, "must be > 0"),
            ("frontier_ratio", 0.0 <= self.frontier_ratio <= 1.0, "must be in [0, 1]"),
            (
                "connection_range",
                self.connection_range is None or self.connection_range > 0,
                "must be > 0",
            ),
            ("cost_threshold", self.cost_threshold > 0, "must be > 0"),
        ]
        problems = [FieldProblem(name, why) for name, ok, why in checks if not ok]
        if problems:
            raise InputError(problems, "planner options")


#: Default step as a fraction of the space's maximum extent (as T-RRT's).
STEP_FRACTION = 0.1


class _Tree:
    """Nodes (configurations, embeddings, parents, costs) and the tree's temperature."""

    def __init__(self, root: NDArray, cost: float, weights: NDArray, temperature: float):
        self.q = np.empty((256, 9))
        self.embedding = np.empty((256, EMBEDDING))
        self.parent = np.empty(256, dtype=np.int64)
        self.cost = np.empty(256)
        self.size = 0
        self.weights = weights
        self.low = self.high = cost
        self.temperature = temperature
        self.radius = np.empty(256)
        self.cells: dict = {}
        self.cell_keys: list = []
        self.cell_size = getattr(self, 'cell_size', 0.25)
        self.root_radius = getattr(self, 'root_radius', 1.0)
        self.add(root, -1, cost)

    def add(self, q: NDArray, parent: int, cost: float) -> int:
        if self.size == len(self.q):
            self.q = np.concatenate([self.q, np.empty_like(self.q)])
            self.embedding = np.concatenate([self.embedding, np.empty_like(self.embedding)])
            self.parent = np.concatenate([self.parent, np.empty_like(self.parent)])
            self.cost = np.concatenate([self.cost, np.empty_like(self.cost)])
            self.radius = np.concatenate([self.radius, np.empty_like(self.radius)])
        index = self.size
        self.radius[index] = self.radius[parent] if parent >= 0 else self.root_radius
        key = (int(q[0] // self.cell_size), int(q[1] // self.cell_size), int(q[2] // self.cell_size))
        members = self.cells.get(key)
        if members is None:
            self.cells[key] = members = []
            self.cell_keys.append(key)
        members.append(index)
        self.q[index] = q
        embed_into(self.q[index], self.weights, self.embedding[index])
        self.parent[index], self.cost[index] = parent, cost
        self.low, self.high = min(self.low, cost), max(self.high, cost)
        self.size += 1
        return index

    def path_to(self, index: int) -> NDArray[np.float64]:
        return path_from_root(self.q, self.parent, index)


class BiTRRT:
    """Bidirectional T-RRT with alpha repair (module docstring)."""

    def __init__(
        self,
        space: ConfigurationSpace,
        validity: CompiledChecker,
        config: BiTRRTConfig | None = None,
        name: str = "bitrrt",
    ) -> None:
        config = config or BiTRRTConfig()
        extent = space.maximum_extent
        step = config.step or STEP_FRACTION * extent
        self.config = replace(
            config,
            step=step,
            frontier_threshold=config.frontier_threshold or 0.01 * extent,
            connection_range=config.connection_range or 10.0 * step,
        )
        #: the resolved lengths (the config's None filled in above)
        self.frontier_threshold: float = self.config.frontier_threshold or 0.0
        self.connection_range: float = self.config.connection_range or 0.0
        self.space, self.validity, self.name = space, validity, name
        self.space_weights = validity.compiled.model[4]

    def _energy(self, cost: float) -> float:
        return math.log(cost) if self.config.log_cost else cost

    def _accepts(self, tree: _Tree, c_from: float, c_to: float, counts: dict) -> bool:
        """transitionTest (OMPL BiTRRT) in the tree's direction of growth."""
        cfg = self.config
        if c_to > cfg.cost_threshold:
            return False
        if c_to <= self.free_level:
            return True
        climb = self._energy(c_to) - self._energy(c_from)
        if climb <= 0.0:
            return True
        if climb < tree.temperature * math.log(2.0):  # exp(-climb / T) > 0.5
            spread = self._energy(tree.high) - self._energy(tree.low)
            if spread > 0.0:
                tree.temperature /= math.exp(min(climb / (cfg.cost_range_fraction * spread), 700))
            return True
        tree.temperature *= math.exp(cfg.temperature_rate)
        counts["transition"] += 1
        return False

    def _frontier_allows(self, distance: float, counts: dict) -> bool:
        """minExpansionControl (OMPL BiTRRT)."""
        if distance > self.frontier_threshold:
            counts["frontier"] += 1
            return True
        if counts["refining"] / counts["frontier"] > self.config.frontier_ratio:
            counts["refinement"] += 1
            return False
        counts["refining"] += 1
        return True

    def _grow(self, tree: _Tree, near: int, target: NDArray, repair: int, counts: dict, out):
        """One extension of ``tree`` from node ``near``; (outcome, new index or -1)."""
        cfg, checker = self.config, self.validity
        outcome, cost = extend(
            tree.q[near],
            target,
            cfg.step,
            repair,
            checker.resolution,
            checker.compiled.model,
            checker.work,
            out,
            cfg.partial,
        )
        if outcome == BLOCKED and cfg.reshape_first:
            middle = np.empty(9)
            middle_cost = reshape_first(
                tree.q[near], out, checker.resolution, checker.compiled.model, checker.work, middle
            )
            if middle_cost < math.inf and self._accepts(
                tree, float(tree.cost[near]), middle_cost, counts
            ):
                counts["reshaped"] += 1
                near = tree.add(middle, near, middle_cost)
                outcome = ADVANCED
        if outcome in (FAILED, BLOCKED) or (
            checker.has_meshes and not checker.motion_is_valid(tree.q[near], out)
        ):
            counts["invalid"] += 1
            return FAILED, -1
        distance = float(np.linalg.norm(tree.embedding[near] - self._embed(out)))
        if not self._accepts(tree, float(tree.cost[near]), cost, counts):
            return FAILED, -1
        if not self._frontier_allows(distance, counts):
            return FAILED, -1
        return outcome, tree.add(out, near, cost)

    def _embed(self, q: NDArray) -> NDArray:
        embedding = np.empty(EMBEDDING)
        embed_into(q, self.space_weights, embedding)
        return embedding

    def _connect(self, tree: _Tree, target: NDArray, counts: dict, out) -> int:
        """Grow ``tree`` towards ``target`` until it reaches it (the node's index) or not
        (-1)."""
        near, distance = nearest(tree.embedding, tree.size, self._embed(target))
        if distance > self.connection_range:
            return -1
        while True:
            outcome, index = self._grow(tree, near, target, REPAIR_UNLESS_REACHED, counts, out)
            if outcome == FAILED:
                return -1
            if outcome == REACHED:
                return index
            near = index

    def solve(
        self,
        start: NDArray[np.float64],
        goal: NDArray[np.float64],
        termination: TerminationCondition,
        seed: int = 0,
        progress: Callable[[PlanningProgress], None] | None = None,
    ) -> PlannerResult:
        """Grow trees from ``start`` and ``goal`` until they meet or ``termination`` stops."""
        clock = time.perf_counter()
        start, goal = np.asarray(start, dtype=float), np.asarray(goal, dtype=float)
        cfg = self.config
        counts = dict.fromkeys(
            ("X", "invalid", "transition", "refinement", "refining", "frontier", "reshaped"), 0
        )
        counts["frontier"] = 1  # OMPL's count starts at 1 (no division by zero)
        trees: list[_Tree] = []

        def finish(status: PlannerStatus, path=None, reason="") -> PlannerResult:
            stats = PlannerStatistics(
                planner=self.name,
                seed=seed,
                time=time.perf_counter() - clock,
                nodes=sum(t.size for t in trees),
                expansion_attempts=counts["X"],
                rejected_refinement=counts["refinement"],
                rejected_invalid=counts["invalid"],
                rejected_transition=counts["transition"],
                final_temperature=trees[0].temperature if trees else math.nan,
            )
            return PlannerResult(status, np.empty((0, 9)) if path is None else path, stats, reason)

        cost, valid = self.validity.compiled.states(
            np.ascontiguousarray(np.stack([start, goal])), True, self.validity.work
        )
        if self.validity.has_meshes:
            valid &= self.validity.is_valid(np.stack([start, goal]))
        for ok, q, status in ((valid[0], start, PlannerStatus.INVALID_START),
                              (valid[1], goal, PlannerStatus.INVALID_GOAL)):  # fmt: skip
            if not ok:
                return finish(status, reason=self.validity.describe_invalid(q))
        self.free_level = float(max(cost)) if cfg.free_below_endpoints else -math.inf
        for root, c in ((start, cost[0]), (goal, cost[1])):
            t0 = cfg.init_temperature or (0.1 if cfg.log_cost else 1e-6 * float(c))
            trees.append(_Tree.__new__(_Tree))
            trees[-1].cell_size = cfg.cell_size
            trees[-1].root_radius = cfg.local_radius
            _Tree.__init__(trees[-1], root, float(c), self.space_weights, t0)
        sampler: Sampler = make_sampler(cfg.sampler, self.space, self.validity, seed, start)
        out = np.empty(9)
        rng = np.random.default_rng([seed, 2])
        current, next_report, gap = 0, cfg.progress_interval, math.inf
        while (stop := termination()) is None:
            counts["X"] += 1
            if cfg.balance:
                current = 0 if trees[0].size <= trees[1].size else 1
            tree, other = trees[current], trees[1 - current]
            u = rng.random()
            local = u < cfg.local_share + cfg.other_share
            if local:
                if u < cfg.other_share:
                    chosen = rng.integers(other.size)
                    node = other.q[chosen]
                elif cfg.cell_select:
                    members = tree.cells[tree.cell_keys[rng.integers(len(tree.cell_keys))]]
                    chosen = members[rng.integers(len(members))]
                else:
                    chosen = rng.integers(tree.size)
                if u >= cfg.other_share:
                    node = tree.q[chosen]
                noise = np.empty(9)
                r = cfg.local_radius
                noise[:3] = rng.normal(0, r / math.sqrt(3), 3)
                noise[3:6] = rng.normal(0, r / math.sqrt(3) / self.space.rotation_weight, 3)
                noise[6:] = rng.normal(0, r / math.sqrt(3) / self.space.alpha_weight, 3)
                target = np.empty(9)
                perturb_into(node, noise, self.validity.compiled.model[0], target)
            else:
                target = sampler.next()
            near, _ = nearest(tree.embedding, tree.size, self._embed(target))
            mode = rng.random()
            if mode < cfg.translate_share:
                target = np.concatenate([target[:3], tree.q[near, 3:]])
            elif mode < cfg.translate_share + cfg.rotate_share:
                target = np.concatenate([tree.q[near, :3], target[3:]])
            repair = cfg.repair_alphas and rng.random() < cfg.repair_share
            outcome, index = self._grow(
                tree, near, target, REPAIR if repair else NO_REPAIR, counts, out
            )  # fmt: skip
            if cfg.adaptive_radius:
                if outcome == FAILED:
                    tree.radius[near] = max(0.05, 0.7 * tree.radius[near])
                else:
                    tree.radius[near] = min(cfg.local_radius, 1.5 * tree.radius[near])
            if outcome != FAILED:
                new = tree.q[index].copy()
                _, gap_now = nearest(other.embedding, other.size, tree.embedding[index])
                gap = min(gap, gap_now)
                met = self._connect(other, new, counts, out)
                if met >= 0:
                    first, second = (tree, other) if current == 0 else (other, tree)
                    ends = (index, met) if current == 0 else (met, index)
                    path = np.concatenate(
                        [first.path_to(ends[0]), second.path_to(ends[1])[::-1][1:]]
                    )
                    return finish(PlannerStatus.EXACT_SOLUTION, path)
            current = 1 - current
            if progress is not None and termination.elapsed() >= next_report:
                next_report = termination.elapsed() + cfg.progress_interval
                progress(
                    PlanningProgress(
                        self.name, counts["X"], sum(t.size for t in trees), gap,
                        termination.elapsed(),
                    )
                )  # fmt: skip
        logger.info("%s stopped (%s) after %d attempts", self.name, stop, counts["X"])
        return finish(stop, reason=f"{stop}: trees {gap:.3g} apart at their closest")
