"""OMPL's RRT, RRTConnect and TRRT as peers on our checker: they run in a child process, return our
result type, and their paths pass our own motion checks."""

from __future__ import annotations

import itertools
import sys

import numpy as np
import pytest

from flycrane.planning.algorithms.ompl_peers import OmplPlanner
from flycrane.planning.algorithms.trrt import TRRTConfig
from flycrane.planning.result import PlannerStatus, TerminationCondition
from flycrane.planning.state_space import ConfigurationSpace
from tests.flycrane.planning.toy_validity import ToyValidity

START = np.array([-2.0, 0.0, 3.0, 0.0, 0.0, 0.0, 1.0, 1.0, 1.0])
GOAL = np.array([2.0, 1.0, 4.0, 0.0, 0.1, 1.0, 1.0, 1.0, 1.0])


@pytest.fixture(scope="module")
def free_space(system):
    space = ConfigurationSpace.for_system(system, (-4, -4, 1), (4, 4, 8), 0.5, 0.3, 1.8)
    return space, ToyValidity(system, space)


@pytest.mark.parametrize("algorithm", ["rrt", "rrtconnect", "trrt"])
def test_ompl_peer_solves_and_its_path_is_valid_for_us(free_space, algorithm):
    space, validity = free_space
    result = OmplPlanner(space, validity, algorithm).solve(
        START, GOAL, TerminationCondition(60.0), seed=1
    )
    assert result.status is PlannerStatus.EXACT_SOLUTION, result.reason
    np.testing.assert_allclose(result.path[0], START, atol=1e-12)
    np.testing.assert_allclose(result.path[-1], GOAL, atol=1e-12)
    assert all(
        validity.motion_is_valid(a, b)
        for a, b in zip(result.path[:-1], result.path[1:], strict=False)
    )
    assert result.statistics.nodes >= 2 and result.statistics.expansion_attempts >= 1
    assert "ompl" not in sys.modules  # the parent never loads libompl (exit-time double free)


@pytest.mark.parametrize("algorithm", ["rrt", "rrtconnect", "trrt"])
def test_ompl_peer_does_not_stop_where_the_goal_is_out_of_reach(free_space, system, algorithm):
    """Nodes just before a wall lie within reach of the goal behind it, but the straight
    motion is blocked: the run must go on over the wall, not end there and fail."""
    space, _ = free_space
    wall = ToyValidity(system, space, [((-0.2, -4, 0), (0.2, 4, 3.5))])  # below the drones
    start, goal = START.copy(), START.copy()
    goal[0] = 1.0  # 3 from the start, behind the wall
    config = TRRTConfig(step=1.0, goal_connection=2.0)
    result = OmplPlanner(space, wall, algorithm, config).solve(
        start, goal, TerminationCondition(60.0), seed=1
    )
    assert result.status is PlannerStatus.EXACT_SOLUTION, result.reason
    assert all(wall.motion_is_valid(a, b) for a, b in itertools.pairwise(result.path))
    assert result.path[:, 2].max() > 3.5  # P over the wall


def test_ompl_peer_reports_invalid_start_without_a_child(free_space):
    space, validity = free_space
    bad = START.copy()
    bad[6:] = 1.6  # slack cable
    result = OmplPlanner(space, validity, "rrt").solve(bad, GOAL, TerminationCondition(5.0))
    assert result.status is PlannerStatus.INVALID_START


def test_cancelling_kills_the_ompl_child(free_space, system):
    space, _ = free_space
    walled = ToyValidity(system, space, [((-1, -4, 0), (1, 4, 8))])  # no way through
    cancel = TerminationCondition(60.0, should_stop=lambda: cancel.elapsed() > 3.0)
    result = OmplPlanner(space, walled, "rrt").solve(START, GOAL, cancel)
    assert result.status is PlannerStatus.CANCELLED
    assert result.statistics.time < 10.0
