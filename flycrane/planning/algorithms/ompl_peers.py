"""OMPL's RRT, RRTConnect and TRRT as peer planners on our validity checker and cost.

They answer to the same :class:`~flycrane.planning.algorithms.trrt.Validity` and return the same
:class:`~flycrane.planning.result.PlannerResult`, so the user can select them and the
benchmark can compare against them.

- State space: OMPL's compound R^3 x SO2(phi) x R(theta) x SO2(sigma) x SO2^3(alpha), so
  interpolation is ours exactly (linear, angles the short way). OMPL's distance is the
  weighted sum of the parts (weights: our lever arms rho_R, rho_a), not our chordal
  metric, and theta is sampled uniformly in [0, max_tilt] rather than on the cap.
- Validity: OMPL calls our ``is_valid`` per state and our ``motion_is_valid`` per motion
  (a Python MotionValidator), so both planners check exactly the same motions. X counts
  motion checks, one per OMPL iteration that reaches one.
- Goal: as our planners, OMPL's stop on a node within ``goal_connection x step`` of the
  goal (our chordal distance) from which the straight motion to the exact goal is valid;
  the path is completed by that motion. (A plain goal ball lets OMPL stop on any node in
  the ball, and on the Rescue most such nodes cannot reach the goal, 5 cm above the roofs.)
- Objective (TRRT): ``MechanicalWorkOptimizationObjective`` with our cost as stateCost;
  TRRT starts at our initial temperature (1e-6 * c(q_start)) instead of OMPL's 100, which
  suits neither cost scale.
- Isolation: the ompl 1.7.0 wheel loads two copies of libompl, whose static destructors
  double-free at interpreter exit (SIGABRT). Every OMPL run therefore happens in a spawned
  child process that leaves with ``os._exit`` after sending its result; the parent never
  imports ompl. Cancelling kills the child.
"""

from __future__ import annotations

import multiprocessing
import os
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Literal

import numpy as np
from numpy.typing import NDArray

from flycrane.planning.algorithms.trrt import STEP_FRACTION, TRRTConfig
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

#: How often the parent polls the child for a result or a cancel request [s].
POLL_INTERVAL = 0.05


@dataclass(frozen=True)
class _Job:
    space: ConfigurationSpace
    validity: Validity
    algorithm: Literal["rrt", "rrtconnect", "trrt"]
    config: TRRTConfig
    start: NDArray[np.float64]
    goal: NDArray[np.float64]
    time_budget: float
    seed: int


class OmplPlanner:
    """OMPL's ``og.RRT``, ``og.RRTConnect`` or ``og.TRRT`` behind our planner interface."""

    def __init__(
        self,
        space: ConfigurationSpace,
        validity: Validity,
        algorithm: Literal["rrt", "rrtconnect", "trrt"],
        config: TRRTConfig | None = None,
    ) -> None:
        self.space, self.validity, self.algorithm = space, validity, algorithm
        self.config = config or (TRRTConfig() if algorithm == "trrt" else TRRTConfig.rrt())
        self.name = f"ompl-{algorithm}"
        self.objective: OptimizationObjective = (
            MechanicalWork(validity.cost, space) if algorithm == "trrt" else PathLength(space)
        )

    def solve(
        self,
        start: NDArray[np.float64],
        goal: NDArray[np.float64],
        termination: TerminationCondition,
        seed: int = 0,
        progress: Callable[[PlanningProgress], None] | None = None,
    ) -> PlannerResult:
        clock = time.perf_counter()
        for q, status in ((start, PlannerStatus.INVALID_START), (goal, PlannerStatus.INVALID_GOAL)):
            if not self.validity.is_valid(np.asarray(q, dtype=float)[None])[0]:
                return PlannerResult(
                    status,
                    np.empty((0, 9)),
                    PlannerStatistics(self.name, seed, 0.0, 0, 0),
                    self.validity.describe_invalid(np.asarray(q, dtype=float)),
                )
        budget = max(0.0, termination.time_budget - termination.elapsed())
        job = _Job(
            self.space,
            self.validity,
            self.algorithm,
            self.config,
            np.asarray(start, float),
            np.asarray(goal, float),
            budget,
            seed,
        )
        context = multiprocessing.get_context("spawn")
        receiver, sender = context.Pipe(duplex=False)
        child = context.Process(target=_child_main, args=(sender, job), daemon=True)
        child.start()
        sender.close()
        try:
            while not receiver.poll(POLL_INTERVAL):
                stop = termination.should_stop is not None and termination.should_stop()
                if stop or not child.is_alive():
                    child.kill()
                    child.join()
                    status = PlannerStatus.CANCELLED if stop else PlannerStatus.TIMEOUT
                    reason = "cancelled" if stop else f"OMPL process ended ({child.exitcode})"
                    stats = PlannerStatistics(self.name, seed, time.perf_counter() - clock, 0, 0)
                    return PlannerResult(status, np.empty((0, 9)), stats, reason)
            outcome = receiver.recv()
        finally:
            receiver.close()
            child.join(timeout=5)
        if isinstance(outcome, BaseException):
            raise outcome
        status, path, nodes, attempts = outcome
        stats = PlannerStatistics(self.name, seed, time.perf_counter() - clock, nodes, attempts)
        reason = "" if status is PlannerStatus.EXACT_SOLUTION else f"{status} after {budget:.3g} s"
        return PlannerResult(status, path, stats, reason)


def _child_main(sender, job: _Job) -> None:
    """Plan with OMPL in this (spawned) process, send the outcome, leave without atexit."""
    try:
        sender.send(_solve(job))
    except BaseException as error:
        sender.send(error)
    finally:
        sender.close()
        os._exit(0)  # skip libompl's double-freeing static destructors (module docstring)


def _solve(job: _Job) -> tuple[PlannerStatus, NDArray[np.float64], int, int]:
    from ompl import base as ob
    from ompl import geometric as og
    from ompl import util as ou

    ou.RNG.setSeed(job.seed + 1)  # OMPL refuses seed 0
    ou.setLogLevel(ou.LogLevel.LOG_WARN)
    space = ob.CompoundStateSpace()
    position = ob.RealVectorStateSpace(3)
    bounds = ob.RealVectorBounds(3)
    for axis in range(3):
        bounds.setLow(axis, job.space.position_low[axis])
        bounds.setHigh(axis, job.space.position_high[axis])
    position.setBounds(bounds)
    tilt = ob.RealVectorStateSpace(1)
    tilt.setBounds(0.0, job.space.max_tilt)
    space.addSubspace(position, 1.0)
    space.addSubspace(ob.SO2StateSpace(), job.space.rotation_weight)
    space.addSubspace(tilt, job.space.rotation_weight)
    space.addSubspace(ob.SO2StateSpace(), job.space.rotation_weight)
    for _ in range(3):
        space.addSubspace(ob.SO2StateSpace(), job.space.alpha_weight)

    def to_q(state) -> NDArray[np.float64]:
        return np.array(
            [
                state[0][0],
                state[0][1],
                state[0][2],
                state[1].value,
                state[2][0],
                state[3].value,
                state[4].value,
                state[5].value,
                state[6].value,
            ]
        )

    def set_state(state, q: NDArray) -> None:
        for axis in range(3):
            state()[0][axis] = float(q[axis])
        state()[1].value, state()[2][0], state()[3].value = float(q[3]), float(q[4]), float(q[5])
        for k in range(3):
            state()[4 + k].value = float(q[6 + k])

    info = ob.SpaceInformation(space)
    info.setStateValidityChecker(
        ob.StateValidityCheckerFn(lambda s: bool(job.validity.is_valid(to_q(s)[None])[0]))
    )
    motion_checks = [0]

    class Motions(ob.MotionValidator):
        def checkMotion(self, a, b, *last_valid) -> bool:
            motion_checks[0] += 1
            return job.validity.motion_is_valid(to_q(a), to_q(b))

    motions = Motions(info)
    info.setMotionValidator(motions)
    info.setup()

    class StaticsCost(ob.MechanicalWorkOptimizationObjective):
        def stateCost(self, state):
            return ob.Cost(float(job.validity.cost(to_q(state)[None])[0]))

    step = job.config.step or STEP_FRACTION * job.space.maximum_extent
    reach = job.config.goal_connection * step

    class ReachableGoal(ob.GoalState):
        """The goal state, satisfied from within ``reach`` by a valid straight motion."""

        def distanceGoal(self, state):
            q = to_q(state)
            distance = float(job.space.distance(q, job.goal)[0])
            if distance <= reach and job.validity.motion_is_valid(q, job.goal):
                return distance
            return distance + reach  # never within the threshold

    problem = ob.ProblemDefinition(info)
    start, goal_state = ob.State(space), ob.State(space)
    set_state(start, job.start)
    set_state(goal_state, job.goal)
    goal = ReachableGoal(info)
    goal.setState(goal_state)
    goal.setThreshold(reach)
    problem.addStartState(start)
    problem.setGoal(goal)
    if job.algorithm == "trrt":
        problem.setOptimizationObjective(StaticsCost(info))
        planner = og.TRRT(info)
        c_start = float(job.validity.cost(job.start[None])[0])
        planner.setInitTemperature(job.config.init_temperature or 1e-6 * c_start)
        planner.setTempChangeFactor(job.config.temperature_rate)
        planner.setFrontierNodeRatio(job.config.refinement_ratio)
    elif job.algorithm == "rrtconnect":
        planner = og.RRTConnect(info)  # grows a tree from the goal state itself: no bias
    else:
        planner = og.RRT(info)
    planner.setRange(step)
    if job.algorithm != "rrtconnect":
        planner.setGoalBias(job.config.goal_bias)
    planner.setProblemDefinition(problem)
    planner.setup()
    solved = planner.solve(ob.timedPlannerTerminationCondition(job.time_budget))
    data = ob.PlannerData(info)
    planner.getPlannerData(data)
    exact = bool(solved) and problem.hasExactSolution()
    path = np.empty((0, 9))
    if exact:
        geometric = problem.getSolutionPath()
        path = np.array([to_q(geometric.getState(i)) for i in range(geometric.getStateCount())])
        if not np.allclose(path[-1], job.goal):  # its motion was checked by ReachableGoal
            path = np.concatenate([path, job.goal[None]])
    status = PlannerStatus.EXACT_SOLUTION if exact else PlannerStatus.TIMEOUT
    return status, path, data.numVertices(), motion_checks[0]
