"""The bidirectional T-RRT (``bitrrt``): statistics over seeds, determinism per seed, valid
paths by the checker's own evidence, and the corridor T-RRT does not enter.

Each returned path is judged independently of the planner: every configuration and every
motion between consecutive ones by the validity checker (compiled, held to python-fcl by
tests/flycrane/test_collision_kernel.py), and its end points against the task's.
"""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from pydantic import ValidationError

from flycrane.planning.bitrrt import BiTRRT
from flycrane.planning.planners import PlannerOptions, plan
from flycrane.planning.problem import PlanningProblem
from flycrane.planning.result import PlannerStatus, TerminationCondition

#: Generous: the runs below take well under a second to a few seconds (BENCHMARKS.md);
#: the budget only bounds a machine under heavy load, it is not what is tested.
BUDGET = 120.0


def assert_valid_path(problem: PlanningProblem, path: np.ndarray) -> None:
    assert len(path) >= 2
    np.testing.assert_allclose(path[0], problem.start, atol=1e-9)
    np.testing.assert_allclose(path[-1], problem.goal, atol=1e-9)
    assert problem.validity.is_valid(path).all()
    for a, b in itertools.pairwise(path):
        assert problem.validity.motion_is_valid(a, b)


@pytest.mark.parametrize("scene", ["rescue", "corridor"])
def test_solves_every_seed_with_valid_paths(scene):
    problem = PlanningProblem.named(scene)
    planner = BiTRRT(problem.space, problem.validity)
    for seed in range(5):
        result = planner.solve(problem.start, problem.goal, TerminationCondition(BUDGET), seed)
        assert result.status is PlannerStatus.EXACT_SOLUTION, (scene, seed, result.reason)
        assert_valid_path(problem, result.path)


def test_same_seed_same_path_other_seed_other_path():
    problem = PlanningProblem.named("corridor")
    planner = BiTRRT(problem.space, problem.validity)

    def path(seed: int) -> np.ndarray:
        return planner.solve(problem.start, problem.goal, TerminationCondition(BUDGET), seed).path

    first = path(3)
    np.testing.assert_array_equal(path(3), first)
    assert path(4).shape != first.shape or not np.array_equal(path(4), first)


def test_selected_by_the_planner_options_and_smoothed_without_climbing():
    problem = PlanningProblem.named("rescue")
    options = PlannerOptions(algorithm="bitrrt", seed=1, time_budget=BUDGET)
    outcome = plan(problem.space, problem.validity, problem.start, problem.goal, options)
    assert outcome.result.statistics.planner == "bitrrt"
    assert_valid_path(problem, outcome.path)
    assert outcome.metrics is not None and np.isfinite(outcome.metrics.max_cost)


def test_trrt_only_options_are_refused_for_bitrrt():
    with pytest.raises(ValidationError, match="init_temperature"):
        PlannerOptions(algorithm="bitrrt", init_temperature=1.0)
    PlannerOptions(algorithm="trrt", init_temperature=1.0)  # T-RRT's own option
