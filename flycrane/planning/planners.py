"""Planner selection and the planning run: plan, smooth, polish, refine, measure.

:class:`PlannerOptions` is the user-facing schema (tasks, CLI, benchmark); :func:`plan`
runs the chosen planner, smooths its path with random shortcuts (cost-aware for the
cost-aware planners), polishes its formation (bitrrt's by default), lowers its average
cost when asked to (``improve_time``, :mod:`flycrane.planning.refinement`) and computes the
path metrics.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Literal

import numpy as np
from numpy.typing import NDArray
from pydantic import BaseModel, ConfigDict, Field, model_validator

from flycrane.planning.algorithms.bitrrt import BiTRRT, BiTRRTConfig, PayloadMeshes
from flycrane.planning.algorithms.ompl_peers import OmplPlanner
from flycrane.planning.algorithms.trrt import TRRT, TRRTConfig
from flycrane.planning.formation_polish import PolishConfig, polish_formation
from flycrane.planning.interfaces import CompiledChecker, Planner
from flycrane.planning.metrics import PathMetrics, path_metrics
from flycrane.planning.refinement import RefinementConfig, refine_path
from flycrane.planning.result import PlannerResult, PlanningProgress, TerminationCondition
from flycrane.planning.robust_clearance import RobustClearance
from flycrane.planning.smoothing import ShortcutConfig, shortcut_path
from flycrane.planning.state_space import ConfigurationSpace
from flycrane.quantities import MAX_LENGTH, MAX_TIME_BUDGET, Seed

Algorithm = Literal["trrt", "rrt", "bitrrt", "ompl-trrt", "ompl-rrt", "ompl-rrtconnect"]
#: Options of the unidirectional T-RRT that the bidirectional one has no use for.
TRRT_ONLY = ("goal_bias", "goal_connection", "init_temperature", "refinement_ratio")


class PlannerOptions(BaseModel):
    """Which planner, with which parameters (default: ``bitrrt``, which solves the users'
    scenes T-RRT does not, and whose polished paths, where T-RRT solves, cost less and keep
    every margin of Fig. 6 at least as well: BENCHMARKS.md "Planner v2"; ``improve_time``
    refines them to a few times lower average cost on request; with a payload given as
    triangle meshes, which bitrrt does not check, the default is ``trrt``, the paper's
    T-RRT)."""

    # Finite numbers only; seeds and counts are integers, not booleans or strings.
    model_config = ConfigDict(frozen=True, extra="forbid", allow_inf_nan=False)

    algorithm: Algorithm | None = Field(
        None,
        description="bitrrt, trrt (the paper's T-RRT), rrt, or OMPL's peers; None (the "
        "default): bitrrt, or trrt with a payload of triangle meshes, which bitrrt does "
        "not check",
    )
    seed: Seed = Field(0, description="random seed: same seed, same path")
    time_budget: float = Field(
        60.0,
        gt=0,
        le=MAX_TIME_BUDGET,
        description="planning time limit [s]",
        strict=True,
    )
    step: float | None = Field(
        None,
        gt=0,
        le=MAX_LENGTH,
        description="extension step delta [state-space distance]; None: 0.1 x extent",
        strict=True,
    )
    goal_bias: float = Field(0.05, ge=0, le=1, strict=True)
    goal_connection: float = Field(
        2.0,
        gt=0,
        le=100,
        description="try the goal from nodes within this many steps of it",
        strict=True,
    )
    init_temperature: float | None = Field(
        None, gt=0, description="None: 1e-6 c(q_start)", strict=True
    )
    temperature_rate: float = Field(0.1, ge=0, le=1, description="T_rate", strict=True)
    refinement_ratio: float = Field(0.1, ge=0, le=1, description="rho", strict=True)
    cost_threshold: float | None = Field(
        None, gt=0, description="c_max; None: no threshold", strict=True
    )
    smoothing_attempts: int = Field(
        100, ge=0, le=100_000, strict=True, description="random shortcuts"
    )
    polish: bool | None = Field(
        None,
        description="reshape the formation a little at the waypoints to raise the path's "
        "least thrust margin and headroom (flycrane/planning/formation_polish.py); None: "
        "on for bitrrt, off for the paper's planners and OMPL's",
        strict=True,
    )
    improve_time: float = Field(
        0.0,
        ge=0,
        le=3_600,
        description="seconds to lower the path's average cost after smoothing and polish, "
        "keeping it valid and its least margins (flycrane/planning/refinement.py; a few "
        "seconds suffice, it stops once converged); 0, the default: off, because the refined "
        "paths took longer to fly and one came closer to an obstacle on SITL (BENCHMARKS.md "
        '"Anytime improvement")',
        strict=True,
    )

    @model_validator(mode="after")
    def _options_of_the_algorithm(self) -> PlannerOptions:
        # Set to something other than its default: a task written out whole (task.json)
        # carries every option and must read back.
        unused = [
            name
            for name in TRRT_ONLY
            if name in self.model_fields_set
            and getattr(self, name) != type(self).model_fields[name].default
        ]
        if self.algorithm in (None, "bitrrt") and unused:
            raise ValueError(
                f"{', '.join(unused)}: options of trrt and rrt (name the algorithm); bitrrt, "
                "the default, grows two trees and runs its transition test on log c "
                "(flycrane/planning/algorithms/bitrrt.py)"
            )
        return self

    def algorithm_for(self, payload_meshes: bool) -> Algorithm:
        """The planner that runs with a payload of (or without) triangle meshes: bitrrt
        checks obstacle meshes but a payload of primitive shapes only, so the default
        (``algorithm`` None) is trrt there (fcl checks the payload), and bitrrt asked for by
        name is refused. The choice is the data's, not whether a field was set: a stored
        task means what was sent.

        Raises
        ------
        PayloadMeshes
            bitrrt asked for and the payload has meshes.
        """
        if self.algorithm is None:
            return "trrt" if payload_meshes else "bitrrt"
        if self.algorithm == "bitrrt" and payload_meshes:
            raise PayloadMeshes()
        return self.algorithm

    def polishes(self, algorithm: Algorithm) -> bool:
        """Whether the path of ``algorithm`` (the one that runs) is polished."""
        return algorithm == "bitrrt" if self.polish is None else self.polish

    def bitrrt_config(self) -> BiTRRTConfig:
        return BiTRRTConfig(
            step=self.step,
            temperature_rate=self.temperature_rate,
            cost_threshold=math.inf if self.cost_threshold is None else self.cost_threshold,
        )

    def trrt_config(self) -> TRRTConfig:
        """The paper's T-RRT with these options."""
        return TRRTConfig(
            step=self.step,
            goal_bias=self.goal_bias,
            goal_connection=self.goal_connection,
            init_temperature=self.init_temperature,
            temperature_rate=self.temperature_rate,
            refinement_ratio=self.refinement_ratio,
            cost_threshold=np.inf if self.cost_threshold is None else self.cost_threshold,
        )

    def rrt_config(self) -> TRRTConfig:
        """Plain RRT (no transition test) with these options."""
        return TRRTConfig.rrt(
            step=self.step, goal_bias=self.goal_bias, goal_connection=self.goal_connection
        )


def make_planner(
    space: ConfigurationSpace,
    validity: CompiledChecker,
    options: PlannerOptions,
    algorithm: Algorithm | None = None,
):
    """The planner object of ``algorithm`` (default: :meth:`PlannerOptions.algorithm_for`
    the scene); each has ``solve`` and ``name``.

    Raises
    ------
    PayloadMeshes
        bitrrt asked for by name in a scene with triangle meshes.
    """
    algorithm = algorithm or options.algorithm_for(validity.payload_meshes)
    return PLANNERS[algorithm](space, validity, options)


#: How each algorithm's planner is made from the options.
PLANNERS: dict[Algorithm, Callable[[ConfigurationSpace, CompiledChecker, PlannerOptions], Planner]]
PLANNERS = {
    "bitrrt": lambda space, validity, o: BiTRRT(space, validity, o.bitrrt_config()),
    "trrt": lambda space, validity, o: TRRT(space, validity, o.trrt_config()),
    "rrt": lambda space, validity, o: TRRT(space, validity, o.rrt_config()),
    "ompl-trrt": lambda space, validity, o: OmplPlanner(space, validity, "trrt", o.trrt_config()),
    "ompl-rrt": lambda space, validity, o: OmplPlanner(space, validity, "rrt", o.rrt_config()),
    "ompl-rrtconnect": lambda space, validity, o: OmplPlanner(
        space, validity, "rrtconnect", o.rrt_config()
    ),
}


@dataclass(frozen=True)
class PlanningOutcome:
    """A planner's result, its smoothed (and polished) path and the metrics of that path."""

    result: PlannerResult
    path: NDArray[np.float64]  #: smoothed path (M, 9); empty unless solved
    metrics: PathMetrics | None  #: of the smoothed path
    smoothing_time: float  #: seconds spent smoothing, polishing and refining


def plan(
    space: ConfigurationSpace,
    validity: CompiledChecker,
    start: NDArray[np.float64],
    goal: NDArray[np.float64],
    options: PlannerOptions,
    should_stop: Callable[[], bool] | None = None,
    progress: Callable[[PlanningProgress], None] | None = None,
    planner: Planner | None = None,
    algorithm: Algorithm | None = None,
    robust: RobustClearance | None = None,
) -> PlanningOutcome:
    """Plan within ``options.time_budget``, then smooth, polish (:meth:`PlannerOptions.
    polishes`), refine for at most ``options.improve_time`` and measure the path.
    ``planner``: one built with settings the options do not carry (benchmarks of variants);
    by default :func:`make_planner`'s. ``algorithm``: the one that runs, where the caller
    resolved it already (:meth:`PlannerOptions.algorithm_for`). ``robust``: the drones'
    errors a refined path must not be more exposed to than the input (:func:`~flycrane.
    planning.refinement.refine_path`)."""
    termination = TerminationCondition(options.time_budget, should_stop)
    algorithm = algorithm or options.algorithm_for(validity.payload_meshes)
    planner = planner or make_planner(space, validity, options, algorithm)
    result = planner.solve(start, goal, termination, seed=options.seed, progress=progress)
    if not result.status.solved:
        return PlanningOutcome(result, np.empty((0, 9)), None, 0.0)
    clock = time.perf_counter()
    smooth = shortcut_path(
        result.path,
        space,
        validity,
        planner.objective,
        ShortcutConfig(options.smoothing_attempts),
        seed=options.seed,
        termination=TerminationCondition(float("inf"), should_stop),
    )
    if options.polishes(algorithm):
        smooth = polish_formation(
            smooth,
            space,
            validity,
            validity.system,
            PolishConfig(),
            termination=TerminationCondition(float("inf"), should_stop),
        )
    if options.improve_time > 0:
        smooth = refine_path(
            smooth,
            space,
            validity,
            validity.system,
            RefinementConfig(),
            TerminationCondition(options.improve_time, should_stop),
            seed=options.seed,
            robust=robust,
        )
    elapsed = time.perf_counter() - clock
    return PlanningOutcome(result, smooth, path_metrics(smooth, space, validity.cost), elapsed)
