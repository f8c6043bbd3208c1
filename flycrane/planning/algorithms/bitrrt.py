"""Bidirectional T-RRT for users' scenes (``bitrrt``): local and cross-tree sampling,
formation repair, partial extensions.

Devaurs, Siméon, Cortés, "Enhancing the transition-based RRT to deal with complex cost
spaces", ICRA 2013 (T-RRT-Connect), as OMPL's ``BiTRRT`` (src/ompl/geometric/planners/rrt/
src/BiTRRT.cpp) implements it, with the FlyCrane's redundancy used at every extension and
sampling that finds narrow passages without scene-specific bounds. The loop is compiled
(:mod:`flycrane.planning.algorithms.bitrrt_kernel`): this module sets it up and reads its result.

Each iteration: choose a target; extend the current tree from its nearest node by at most
the step; keep the node if the transition test accepts the cost change and the frontier
control allows it; then extend the other tree towards the new node step by step (each
step transition-tested) until it reaches it, fails, or is more than ``connection_range``
away; swap the trees. A path exists when the trees meet.

As OMPL: the transition test sees the cost change in each tree's own direction of growth,
cools by ``exp(dc / (0.1 costRange))`` after an accepted climb and heats by ``exp(T_rate)``
after a refused one; the frontier control refuses refining extensions (shorter than
``frontier_threshold``) beyond ``frontier_ratio`` of the exploring ones. As the paper
(Devaurs et al.), each tree keeps its own temperature.

Beyond OMPL's BiTRRT, each kept because it measured better (BENCHMARKS.md, "Planner v2",
"What each choice buys"):

- Targets. Uniform samples alone leave a tree that starts inside a passage (the Puzzle's
  goal, the rod in the hole) almost no successful extension: nearly every sample lies far
  outside, and the step towards it collides. So a share of the targets are local: a
  Gaussian perturbation (``local_radius``) of a random node of the growing tree
  (``local_share``, as EST grows from its nodes) or of the other tree (``other_share``:
  the growing tree is drawn to where the other one is, which is where the trees must meet).
- Subspace moves: a share of the extensions move only the position (``translate_share``)
  or only the orientation and formation (``rotate_share``) of the nearest node. A passage
  that fits one attitude (a bar through a hole) is crossed by translating; one that fits one
  height band (the Puzzle's short bar above the slab and the long bar below) by turning in
  place.
- Partial extensions (``partial``): where the step collides, the part of it that is valid
  is kept when it is at least ``partial`` long (RRT-Connect's progress, one step at a
  time).
- Alpha repair (``repair_share``): the alphas of a new node are moved from the near
  node's towards the least collision-free value of the repair's objective (a bounded
  descent); a sample's own alphas mean nothing for its pose. The objective is eq. 8 with
  the margins below what the path's endpoints keep counted ``1 + margin_weight`` times
  (:mod:`flycrane.planning.algorithms.extension_kernel`): on eq. 8 alone the repair bought slack the
  path cannot keep with thrust and headroom it can.
- Reshape-first: where the straight motion fails, change the formation in place first.
- Transition test on log c (``log_cost``): the normalized cost spans 1e7-1e11 along one
  path, so a climb worth accepting in a valley (x2) and one out of a cliff (x2) differ by
  orders of magnitude in c and not at all in log c.

Obstacles given as triangle meshes are checked in the compiled loop like primitives
(:mod:`flycrane.world.collision_kernel`); a payload given as a mesh is not, so this planner
refuses it (:class:`PayloadMeshes`); T-RRT plans with fcl there.

Both trees start at the task's start and goal; a path always ends exactly at the goal.
"""

from __future__ import annotations

import logging
import math
import time
from collections.abc import Callable
from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import NDArray

from flycrane.errors import FieldProblem, InputError
from flycrane.model.cable_system import CableSystem
from flycrane.model.cost import cost_margin_factors
from flycrane.model.statics import evaluate_statics
from flycrane.planning.algorithms.bitrrt_kernel import (
    ATTEMPTS,
    FRONTIER,
    FULL,
    INVALID,
    MET,
    N_COUNTERS,
    REFINEMENT,
    TEMPERATURE,
    TRANSITION,
    Forest,
    Params,
    add_node,
    run,
)
from flycrane.planning.algorithms.tree import path_from_root
from flycrane.planning.interfaces import CompiledChecker
from flycrane.planning.objective import MechanicalWork, OptimizationObjective
from flycrane.planning.result import (
    PlannerResult,
    PlannerStatistics,
    PlannerStatus,
    PlanningProgress,
    TerminationCondition,
)
from flycrane.planning.state_space import ConfigurationSpace

logger = logging.getLogger(__name__)


@dataclass(frozen=True)
class BiTRRTConfig:
    """Parameters of the bidirectional T-RRT; None means "from the problem at setup"."""

    step: float | None = None  #: largest extension; None: STEP_FRACTION x the space's extent
    #: share of the extensions whose new node's alphas are repaired (the others keep the
    #: target's: the formation must also explore, e.g. narrow before a corridor)
    repair_share: float = 0.7
    #: weight w of the repair's capped term, log c + w log c_cap: how much more a margin
    #: counts below what the endpoints keep (module docstring; 0: eq. 8 alone)
    margin_weight: float = 1.0
    translate_share: float = 0.3  #: extensions that move the nearest node's position only
    rotate_share: float = 0.3  #: extensions that turn and reshape it in place only
    local_share: float = 0.2  #: targets near a random node of the growing tree
    other_share: float = 0.4  #: targets near a random node of the other tree
    local_radius: float = 1.0  #: the local targets' distance [state-space distance]
    #: least length of a partial extension [state-space distance]; 0: none
    partial: float = 0.2
    #: where the straight motion to a valid new node fails, try reshaping the formation in
    #: place first (:func:`~flycrane.planning.algorithms.extension_kernel.reshape_first`)
    reshape_first: bool = True
    log_cost: bool = True  #: transition test on log c instead of c
    #: accept without a test every move to a cost at most the start's or goal's; False:
    #: T-RRT's test on every climb
    free_below_endpoints: bool = True
    init_temperature: float | None = None  #: None: 0.1 (log c) or 1e-6 c(root) (c)
    temperature_rate: float = 0.1  #: T *= exp(T_rate) after a refused climb (OMPL)
    cost_range_fraction: float = 0.1
    frontier_threshold: float | None = None  #: None: 0.01 x extent (OMPL)
    frontier_ratio: float = 0.1  #: refining / exploring extensions allowed (OMPL)
    connection_range: float | None = None  #: None: 10 x step
    cost_threshold: float = math.inf  #: c_max
    progress_interval: float = 0.5

    def __post_init__(self) -> None:
        shares = ("repair_share", "translate_share", "rotate_share", "local_share", "other_share")
        checks = [(name, 0.0 <= getattr(self, name) <= 1.0, "must be in [0, 1]") for name in shares]
        checks += [
            ("step", self.step is None or self.step > 0, "must be > 0"),
            ("margin_weight", self.margin_weight >= 0, "must be >= 0"),
            (
                "translate_share",
                self.translate_share + self.rotate_share <= 1.0,
                "translate_share + rotate_share must be <= 1",
            ),
            (
                "local_share",
                self.local_share + self.other_share <= 1.0,
                "local_share + other_share must be <= 1",
            ),
            ("local_radius", self.local_radius > 0, "must be > 0"),
            ("partial", self.partial >= 0, "must be >= 0"),
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
#: Expansion attempts per compiled call between termination checks (about 10-50 ms).
BATCH = 256
#: Nodes per tree the arrays hold at first (they double when full).
INITIAL_CAPACITY = 1024
#: Grid cell of the nearest-neighbour index [m] (:mod:`flycrane.planning.algorithms.neighbours`).
GRID_CELL = 0.5


#: Why bitrrt refuses a payload of meshes (module docstring).
MESH_REASON = (
    "bitrrt checks a payload of boxes, cylinders and spheres only and this payload has "
    "triangle meshes: plan it with trrt, which checks them with fcl"
)


class PayloadMeshes(InputError):
    """bitrrt cannot plan with a payload of triangle meshes (module docstring)."""

    def __init__(self) -> None:
        super().__init__([FieldProblem("algorithm", MESH_REASON)], "planner options")


def margin_caps(system: CableSystem, ends: NDArray[np.float64]) -> NDArray[np.float64]:
    """The repair's caps (module docstring): the least slack, overload and thrust factors
    of eq. 8 at the path's endpoints ``ends`` (2, 9), shape (3,)."""
    factors = cost_margin_factors(system, evaluate_statics(system, ends))
    return np.array([factors[:, 3:9].min(), factors[:, 9:15].min(), factors[:, :3].min()])


class BiTRRT:
    """Bidirectional T-RRT (module docstring)."""

    def __init__(
        self,
        space: ConfigurationSpace,
        validity: CompiledChecker,
        config: BiTRRTConfig | None = None,
        name: str = "bitrrt",
    ) -> None:
        if validity.payload_meshes:
            raise PayloadMeshes()
        config = config or BiTRRTConfig()
        extent = space.maximum_extent
        step = config.step or STEP_FRACTION * extent
        self.config = replace(
            config,
            step=step,
            frontier_threshold=config.frontier_threshold or 0.01 * extent,
            connection_range=config.connection_range or 10.0 * step,
        )
        self.space, self.validity, self.name = space, validity, name
        self.objective: OptimizationObjective = MechanicalWork(validity.cost, space)

    def _params(self, free_level: float, caps: NDArray[np.float64]) -> Params:
        """The loop's numbers: the config's fields of the same names (their Nones filled in
        by __init__), the cost below which climbs are free, the checker's resolution, the
        repair's caps (:func:`margin_caps`)."""
        given = {
            "free_level": free_level,
            "resolution": self.validity.resolution,
            "cap_slack": caps[0],
            "cap_overload": caps[1],
            "cap_thrust": caps[2],
        }
        return Params(
            **{
                name: given[name] if name in given else float(getattr(self.config, name))
                for name in Params.__dataclass_fields__
            }
        )

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
        counters = np.zeros(N_COUNTERS, dtype=np.int64)
        counters[FRONTIER] = 1  # as OMPL's count: the ratio's denominator is never 0
        forest = Forest(INITIAL_CAPACITY, GRID_CELL)

        def finish(status: PlannerStatus, path=None, reason="") -> PlannerResult:
            stats = PlannerStatistics(
                planner=self.name,
                seed=seed,
                time=time.perf_counter() - clock,
                nodes=int(forest.size.sum()),
                expansion_attempts=int(counters[ATTEMPTS]),
                rejected_refinement=int(counters[REFINEMENT]),
                rejected_invalid=int(counters[INVALID]),
                rejected_transition=int(counters[TRANSITION]),
                final_temperature=float(forest.scalars[0, TEMPERATURE])
                if forest.size[0]
                else math.nan,
            )
            return PlannerResult(status, np.empty((0, 9)) if path is None else path, stats, reason)

        ends = np.ascontiguousarray(np.stack([start, goal]))
        cost, valid = self.validity.compiled.states(ends, True, self.validity.work)
        for ok, q, status in ((valid[0], start, PlannerStatus.INVALID_START),
                              (valid[1], goal, PlannerStatus.INVALID_GOAL)):  # fmt: skip
            if not ok:
                return finish(status, reason=self.validity.describe_invalid(q))
        free_level = float(max(cost)) if cfg.free_below_endpoints else -math.inf
        params = self._params(free_level, margin_caps(self.validity.system, ends)).array()
        model, work = self.validity.compiled.model, self.validity.work
        for t, (root, c) in enumerate(zip(ends, cost, strict=True)):
            add_node(forest.arrays(), t, root, -1, float(c), model[4])
            forest.scalars[t, TEMPERATURE] = cfg.init_temperature or (
                0.1 if cfg.log_cost else 1e-6 * float(c)
            )
        rng = np.random.default_rng(seed)
        gap, meet = np.array([math.inf]), np.full(2, -1, dtype=np.int64)
        next_report = cfg.progress_interval
        while (stop := termination()) is None:
            outcome = run(forest.arrays(), rng, params, model, work, counters, gap, meet, BATCH)
            if outcome == MET:
                path = np.concatenate(
                    [
                        path_from_root(forest.q[0], forest.parent[0], int(meet[0])),
                        path_from_root(forest.q[1], forest.parent[1], int(meet[1]))[::-1][1:],
                    ]
                )
                return finish(PlannerStatus.EXACT_SOLUTION, path)
            if outcome == FULL:
                forest.enlarge()
            if progress is not None and termination.elapsed() >= next_report:
                next_report = termination.elapsed() + cfg.progress_interval
                progress(
                    PlanningProgress(
                        self.name, int(counters[ATTEMPTS]), int(forest.size.sum()),
                        float(gap[0]), termination.elapsed(),
                    )
                )  # fmt: skip
        logger.info("%s stopped (%s) after %d attempts", self.name, stop, counters[ATTEMPTS])
        return finish(stop, reason=f"{stop}: trees {gap[0]:.3g} apart at their closest")
