"""Transition-based RRT (T-RRT) and plain RRT, as in the paper's Algorithms 1-3.

Jaillet, Cortés, Siméon, "Sampling-based path planning on configuration-space costmaps",
IEEE T-RO 26(4), 2010; applied to the FlyCrane by Manubens et al., RSS 2013 (section IV-B).

Each iteration (an *expansion attempt*, X in Table I): sample q_rand (the goal with
probability ``goal_bias``), find q_near, apply refinementControl (Algorithm 3), extend by at
most the step delta to q_new, keep it if the motion q_near -> q_new is valid and the
transitionTest (Algorithm 2) accepts the cost change, then try to connect q_new to the goal
when it lies within ``goal_connection`` x delta. Plain RRT is the same loop with the
transition test and the refinement control off: every feasible, collision-free extension
is accepted.

Choices where the paper is silent or scale-dependent:

- Initial temperature. The paper's T = 1e-6 was for its raw cost (values ~10..1000). Our
  normalized cost is ~5e9 at the benchmark's hover pose, so by default
  ``T0 = 1e-6 * c(q_start)``: as cold relative to the problem's cost as the paper's
  choice; the adaptive rule heats it up by 2^T_rate per rejected climb (about 20 rejections
  per factor of 4).
- The uphill test ``exp(-dc / T) > 0.5`` is evaluated as ``dc < T ln 2``, which is the
  same for T > 0 and cannot divide by zero or overflow.
- Cooling ``T /= 2^(dc / (0.1 costRange))`` is skipped while the tree's cost range is zero
  (only the root, or all nodes of equal cost), where it is undefined; OMPL's TRRT does
  the same.
- The final edge into the goal skips the transition test (it still needs a valid motion
  and a cost below c_max). The goal's cost is fixed by the task, so every path climbs to it
  anyway; when the goal is costlier than its surroundings (the benchmark goals hover at
  alpha = 1, ~5e9, next to ~1e9 valleys) the test refuses that last climb while other
  accepted climbs keep cooling T, and the run stalls next to the goal.
- Goal connection from within 2 delta of the goal (``goal_connection``; the paper does not
  say from how far). A goal can sit on a cost cliff: the Puzzle's hover at alpha = 1
  costs 5.65e9 level and is infeasible at a tilt of 0.2, against ~7e8 for the tilted
  low-alpha nodes the tree brings under the slab. From within one step, such nodes just
  outside the step climb the cliff one refused transition at a time; from within two
  steps the straight motion to the goal is tried (and is valid) much sooner
  (BENCHMARKS.md, "Puzzle: calibration and Table I", "Calibration runs").
"""

from __future__ import annotations

import logging
import math
import time
from collections.abc import Callable
from dataclasses import dataclass, replace
from typing import Any

import numpy as np
from numpy.typing import NDArray

from flycrane.errors import FieldProblem, InputError
from flycrane.planning.algorithms.tree import Tree
from flycrane.planning.interfaces import Validity
from flycrane.planning.objective import MechanicalWork, OptimizationObjective, PathLength
from flycrane.planning.result import (
    PlannerResult,
    PlannerStatistics,
    PlannerStatus,
    PlanningProgress,
    TerminationCondition,
)
from flycrane.planning.state_space import ConfigurationSpace

logger = logging.getLogger(__name__)


#: Default step as a fraction of the space's maximum extent (OMPL's RRT uses 1/5); the
#: measurements behind it are in BENCHMARKS.md ("Step size").
STEP_FRACTION = 0.1


@dataclass(frozen=True)
class TRRTConfig:
    """Parameters of T-RRT (and RRT), with the paper's values as defaults."""

    #: delta: largest extension [state-space distance, ~m of drone travel]; None: filled in
    #: at setup as STEP_FRACTION of the space's maximum extent.
    step: float | None = None
    goal_bias: float = 0.05  #: probability of sampling the goal
    goal_connection: float = 2.0  #: try the goal from nodes within this many steps of it
    transition_test: bool = True  #: False gives plain RRT
    refinement_control: bool = True  #: Algorithm 3 on/off
    init_temperature: float | None = None  #: None: 1e-6 * c(q_start) (module docstring)
    temperature_rate: float = 0.1  #: T_rate: T *= 2^T_rate after a refused climb
    cost_range_fraction: float = 0.1  #: the 0.1 of T /= 2^(dc / (0.1 costRange))
    refinement_ratio: float = 0.1  #: rho
    cost_threshold: float = math.inf  #: c_max: costs above it are refused
    progress_interval: float = 0.5  #: seconds between progress reports

    def __post_init__(self) -> None:
        checks = [
            ("step", self.step is None or self.step > 0, "must be > 0"),
            ("goal_bias", 0.0 <= self.goal_bias <= 1.0, "must be in [0, 1]"),
            ("goal_connection", self.goal_connection > 0, "must be > 0"),
            (
                "init_temperature",
                self.init_temperature is None or self.init_temperature > 0,
                "must be > 0",
            ),
            ("temperature_rate", 0.0 <= self.temperature_rate <= 1.0, "must be in [0, 1]"),
            ("cost_range_fraction", self.cost_range_fraction > 0, "must be > 0"),
            ("refinement_ratio", 0.0 <= self.refinement_ratio <= 1.0, "must be in [0, 1]"),
            ("cost_threshold", self.cost_threshold > 0, "must be > 0"),
            ("progress_interval", self.progress_interval > 0, "must be > 0"),
        ]
        problems = [FieldProblem(name, why) for name, ok, why in checks if not ok]
        if problems:
            raise InputError(problems, "planner options")

    @classmethod
    def rrt(cls, **overrides: Any) -> TRRTConfig:
        """Plain RRT: no transition test, no refinement control."""
        return cls(transition_test=False, refinement_control=False, **overrides)


class Temperature:
    """The adaptive temperature of the transition test (Algorithm 2), with its history."""

    def __init__(self, config: TRRTConfig, initial: float) -> None:
        self.config = config
        self.value = initial
        self.history: list[tuple[int, float]] = [(0, initial)]

    def accepts(self, c_from: float, c_to: float, cost_range: float, attempt: int) -> bool:
        """transitionTest(c_i, c_j): True if the move to cost c_to is accepted."""
        if c_to > self.config.cost_threshold:
            return False
        if c_to <= c_from:
            return True
        climb = c_to - c_from
        if climb < self.value * math.log(2.0):  # exp(-climb / T) > 0.5
            if cost_range > 0.0:
                self.value /= 2.0 ** min(
                    climb / (self.config.cost_range_fraction * cost_range), 1e3
                )
                self._record(attempt)
            return True
        self.value *= 2.0**self.config.temperature_rate
        self._record(attempt)
        return False

    def _record(self, attempt: int) -> None:
        self.history.append((attempt, self.value))
        if len(self.history) > 2000:  # keep memory bounded on long runs: drop every other
            self.history = self.history[::2]


def refinement_allowed(
    distance: float, step: float, refinement_nodes: int, nodes: int, ratio: float
) -> bool:
    """refinementControl (Algorithm 3): refuse an expansion towards a sample closer than the
    step (it would only refine the tree) once refinement nodes exceed ``ratio`` of all nodes."""
    return not (distance < step and refinement_nodes > ratio * nodes)


class TRRT:
    """T-RRT (or RRT with :meth:`TRRTConfig.rrt`) over a state space and a validity checker."""

    def __init__(
        self,
        space: ConfigurationSpace,
        validity: Validity,
        config: TRRTConfig | None = None,
        name: str | None = None,
    ) -> None:
        self.space = space
        self.validity = validity
        config = config or TRRTConfig()
        #: delta, filled in from the space when the config leaves it open
        self.step: float = (
            STEP_FRACTION * space.maximum_extent if config.step is None else config.step
        )
        self.config = replace(config, step=self.step)
        self.name = name or ("trrt" if self.config.transition_test else "rrt")
        self.objective: OptimizationObjective = (
            MechanicalWork(validity.cost, space)
            if self.config.transition_test
            else PathLength(space)
        )

    def solve(
        self,
        start: NDArray[np.float64],
        goal: NDArray[np.float64],
        termination: TerminationCondition,
        seed: int = 0,
        progress: Callable[[PlanningProgress], None] | None = None,
    ) -> PlannerResult:
        """Grow a tree from ``start`` until it reaches ``goal`` or ``termination`` says stop."""
        clock = time.perf_counter()
        start, goal = np.asarray(start, dtype=float), np.asarray(goal, dtype=float)
        rng = np.random.default_rng(seed)
        cfg, step = self.config, self.step
        counts = {"X": 0, "refinement": 0, "invalid": 0, "transition": 0}

        def finish(status: PlannerStatus, path=None, reason="", tree=None, temp=None):
            stats = PlannerStatistics(
                planner=self.name,
                seed=seed,
                time=time.perf_counter() - clock,
                nodes=tree.size if tree else 0,
                expansion_attempts=counts["X"],
                rejected_refinement=counts["refinement"],
                rejected_invalid=counts["invalid"],
                rejected_transition=counts["transition"],
                final_temperature=temp.value if temp else math.nan,
                temperature_history=tuple(temp.history[:: max(1, len(temp.history) // 1000)])
                if temp
                else (),
            )
            path = np.empty((0, 9)) if path is None else path
            return PlannerResult(status, path, stats, reason)

        for q, status in ((start, PlannerStatus.INVALID_START), (goal, PlannerStatus.INVALID_GOAL)):
            if not self.validity.is_valid(q[None])[0]:
                return finish(status, reason=self.validity.describe_invalid(q))
        c_start, c_goal = self.validity.cost(np.stack([start, goal]))
        tree = Tree(self.space)
        tree.add(start, -1, float(c_start))
        temperature = Temperature(cfg, cfg.init_temperature or 1e-6 * float(c_start))
        goal_embedding = self.space.embed(goal)[0]
        best_to_goal = float(np.linalg.norm(tree.embedding[0] - goal_embedding))
        next_report = cfg.progress_interval

        def try_extend(near: int, q_new: NDArray, c_new: float, distance: float) -> int | None:
            if not (np.isfinite(c_new) and self.validity.motion_is_valid(tree.q[near], q_new)):
                counts["invalid"] += 1
                return None
            # The climb into the goal is not optional (module docstring).
            optional_climb = q_new is not goal or c_new > cfg.cost_threshold
            if (
                cfg.transition_test
                and optional_climb
                and not temperature.accepts(
                    float(tree.cost[near]), c_new, tree.cost_range(), counts["X"]
                )
            ):
                counts["transition"] += 1
                return None
            return tree.add(q_new, near, c_new, refinement=distance < step)

        while (stop := termination()) is None:
            counts["X"] += 1
            q_rand = goal if rng.random() < cfg.goal_bias else self.space.sample_uniform(rng)[0]
            near, distance = tree.nearest(self.space.embed(q_rand)[0])
            if (
                cfg.refinement_control
                and q_rand is not goal  # goal-biased samples aim at the goal, not at refining
                and not refinement_allowed(
                    distance, step, tree.refinement_nodes, tree.size, cfg.refinement_ratio
                )
            ):
                counts["refinement"] += 1
                continue
            if distance > step:
                q_new = self.space.interpolate(tree.q[near], q_rand, [step / distance])[0]
                distance = step
            else:
                q_new = q_rand
            c_new = float(c_goal) if q_new is goal else float(self.validity.cost(q_new[None])[0])
            added = try_extend(near, q_new, c_new, distance)
            if added is None:
                continue
            if q_new is goal:
                return finish(
                    PlannerStatus.EXACT_SOLUTION, tree.path_to(added), tree=tree, temp=temperature
                )
            to_goal = float(np.linalg.norm(tree.embedding[added] - goal_embedding))
            best_to_goal = min(best_to_goal, to_goal)
            if to_goal <= cfg.goal_connection * step:  # goal-connection attempt
                reached = try_extend(added, goal, float(c_goal), to_goal)
                if reached is not None:
                    return finish(
                        PlannerStatus.EXACT_SOLUTION,
                        tree.path_to(reached),
                        tree=tree,
                        temp=temperature,
                    )
            if progress is not None and termination.elapsed() >= next_report:
                next_report = termination.elapsed() + cfg.progress_interval
                progress(
                    PlanningProgress(
                        self.name, counts["X"], tree.size, best_to_goal, termination.elapsed()
                    )
                )
        logger.info(
            "%s stopped (%s) after %d attempts, %d nodes", self.name, stop, counts["X"], tree.size
        )
        return finish(
            stop,
            reason=f"{stop}: closest node {best_to_goal:.3g} from the goal",
            tree=tree,
            temp=temperature,
        )
