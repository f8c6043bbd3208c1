"""T-RRT and RRT: hand-computed transition tests, refinement control, statuses, statistics."""

from __future__ import annotations

import math

import numpy as np
import pytest

from flycrane.errors import InputError
from flycrane.model.cable_system import CableSystem
from flycrane.planning.algorithms.trrt import TRRT, Temperature, TRRTConfig, refinement_allowed
from flycrane.planning.metrics import path_metrics
from flycrane.planning.result import PlannerStatus, TerminationCondition
from flycrane.planning.smoothing import ShortcutConfig, shortcut_path
from flycrane.planning.state_space import ConfigurationSpace
from tests.flycrane.planning.toy_validity import ToyValidity

START = np.array([-4.0, 0.0, 3.0, 0.0, 0.0, 0.0, 1.0, 1.0, 1.0])
GOAL = np.array([4.0, 0.0, 3.0, 0.0, 0.0, np.pi / 2, 1.0, 1.0, 1.0])
#: A wall at x in [-1, 1] with a 2 m high window at z in [5, 7].
WALL = [((-1, -6, 0), (1, 6, 5)), ((-1, -6, 7), (1, 6, 10))]


@pytest.fixture(scope="module")
def space(system: CableSystem) -> ConfigurationSpace:
    return ConfigurationSpace.for_system(system, (-6, -6, 1), (6, 6, 10), 0.5, 0.3, 1.8)


@pytest.fixture(scope="module")
def wall(system, space) -> ToyValidity:
    return ToyValidity(system, space, WALL)


class TestTransitionTest:
    """Algorithm 2 against values computed by hand."""

    def test_downhill_and_level_moves_are_always_accepted(self):
        t = Temperature(TRRTConfig(), initial=1e-9)
        assert t.accepts(10.0, 10.0, cost_range=5.0, attempt=1)
        assert t.accepts(10.0, 3.0, cost_range=5.0, attempt=1)
        assert t.value == 1e-9  # no temperature change on downhill moves

    def test_uphill_accepted_below_t_ln2_and_cools(self):
        t = Temperature(TRRTConfig(), initial=10.0)
        # exp(-6 / 10) = 0.549 > 0.5: accepted; T /= 2^(6 / (0.1 * 30)) = 2^2 -> 2.5
        assert t.accepts(4.0, 10.0, cost_range=30.0, attempt=7)
        assert t.value == pytest.approx(2.5)
        assert t.history[-1] == (7, pytest.approx(2.5))

    def test_uphill_refused_above_t_ln2_and_heats(self):
        t = Temperature(TRRTConfig(temperature_rate=0.1), initial=10.0)
        # exp(-7 / 10) = 0.497 < 0.5: refused; T *= 2^0.1
        assert not t.accepts(3.0, 10.0, cost_range=30.0, attempt=2)
        assert t.value == pytest.approx(10.0 * 2**0.1)

    def test_cost_threshold_refuses_even_downhill(self):
        t = Temperature(TRRTConfig(cost_threshold=5.0), initial=1e9)
        assert not t.accepts(8.0, 6.0, cost_range=1.0, attempt=1)

    def test_no_cooling_while_cost_range_is_zero(self):
        t = Temperature(TRRTConfig(), initial=10.0)
        assert t.accepts(1.0, 2.0, cost_range=0.0, attempt=1)
        assert t.value == 10.0

    def test_temperature_stays_positive_and_finite(self):
        t = Temperature(TRRTConfig(), initial=1e-300)
        for attempt in range(100):
            t.accepts(0.0, 1e300, cost_range=1e-300, attempt=attempt)
        assert 0.0 < t.value < math.inf


def test_bad_options_name_the_field():
    with pytest.raises(InputError, match="goal_bias: must be in"):
        TRRTConfig(goal_bias=1.5)
    with pytest.raises(InputError, match="step: must be > 0"):
        TRRTConfig(step=0.0)
    with pytest.raises(InputError, match="goal_connection: must be > 0"):
        TRRTConfig(goal_connection=-1.0)


@pytest.mark.parametrize(
    ("distance", "refinement_nodes", "nodes", "allowed"),
    [
        (2.0, 50, 100, True),  # an expansion (not a refinement) is always allowed
        (0.5, 10, 100, True),  # 10 refinement nodes = 0.1 * 100: not above the ratio
        (0.5, 11, 100, False),  # 11 > 10: refining refused
        (1.0, 11, 100, True),  # distance == step is not a refinement
    ],
)
def test_refinement_control_by_hand(distance, refinement_nodes, nodes, allowed):
    assert refinement_allowed(distance, 1.0, refinement_nodes, nodes, 0.1) is allowed


def test_refinement_control_in_the_loop(space, wall):
    # A step larger than the space makes every expansion a refinement: after the first
    # refinement node (1 > 0.1 * 2) every further expansion is refused, goal included.
    planner = TRRT(space, wall, TRRTConfig(step=100.0))
    result = planner.solve(START, GOAL, TerminationCondition(2.0), seed=1)
    assert result.status is PlannerStatus.TIMEOUT
    assert result.statistics.nodes == 2
    assert result.statistics.rejected_refinement > 0


def test_same_seed_same_path(space, wall):
    a = TRRT(space, wall).solve(START, GOAL, TerminationCondition(30.0), seed=5)
    b = TRRT(space, wall).solve(START, GOAL, TerminationCondition(30.0), seed=5)
    assert a.status.solved and b.status.solved
    np.testing.assert_array_equal(a.path, b.path)
    assert a.statistics.expansion_attempts == b.statistics.expansion_attempts


def test_path_is_valid_and_joins_start_to_goal(space, wall):
    result = TRRT(space, wall).solve(START, GOAL, TerminationCondition(30.0), seed=2)
    assert result.status is PlannerStatus.EXACT_SOLUTION
    np.testing.assert_array_equal(result.path[0], START)
    np.testing.assert_array_equal(result.path[-1], GOAL)
    for a, b in zip(result.path[:-1], result.path[1:], strict=True):
        assert wall.motion_is_valid(a, b)
    # the wall forces P and the drones through the window (z in [5, 7]) near x = 0
    assert result.path[:, 2].max() > 4.0


@pytest.mark.parametrize("reach", [1.0, 2.0])
def test_goal_is_tried_from_within_goal_connection_steps(space, wall, reach):
    """The last edge is the goal-connection attempt (or a goal-biased extension): never
    longer than ``goal_connection`` steps, and with 2 steps some runs use the longer reach."""
    config = TRRTConfig.rrt(step=1.0, goal_connection=reach)
    last_edges = []
    for seed in range(6):
        result = TRRT(space, wall, config).solve(START, GOAL, TerminationCondition(30.0), seed)
        assert result.status.solved
        last_edges.append(space.distance(result.path[-2], result.path[-1])[0])
    assert max(last_edges) <= reach + 1e-9
    assert (max(last_edges) > 1.0) == (reach > 1.0)


def test_invalid_start_and_goal_are_statuses_with_reasons(space, wall):
    inside_wall = START.copy()
    inside_wall[0] = 0.0
    result = TRRT(space, wall).solve(inside_wall, GOAL, TerminationCondition(1.0))
    assert result.status is PlannerStatus.INVALID_START and result.reason
    slack = GOAL.copy()
    slack[6:] = 1.6
    assert TRRT(space, wall).solve(START, slack, TerminationCondition(1.0)).status is (
        PlannerStatus.INVALID_GOAL
    )


def test_timeout_and_cancel_are_statuses(space, system):
    closed = ToyValidity(system, space, [((-1, -6, 0), (1, 6, 10))])  # no window: no path
    result = TRRT(space, closed).solve(START, GOAL, TerminationCondition(0.5))
    assert result.status is PlannerStatus.TIMEOUT
    assert result.statistics.nodes > 1 and "closest node" in result.reason
    calls = []
    cancel = TerminationCondition(60.0, should_stop=lambda: len(calls) > 0)
    reports = []

    def progress(report):
        reports.append(report)
        calls.append(1)

    result = TRRT(space, closed, TRRTConfig(progress_interval=0.05)).solve(
        START, GOAL, cancel, progress=progress
    )
    assert result.status is PlannerStatus.CANCELLED
    assert reports and reports[0].nodes >= 1 and reports[0].distance_to_goal > 0


def test_trrt_paths_cost_less_than_rrt_paths_over_seeds(space, wall):
    """Statistical (OMPL-style): both solve every seed; T-RRT's mean avgC is lower."""
    seeds = range(6)
    avg = {}
    for name, config in (("trrt", TRRTConfig()), ("rrt", TRRTConfig.rrt())):
        costs = []
        for seed in seeds:
            planner = TRRT(space, wall, config)
            result = planner.solve(START, GOAL, TerminationCondition(30.0), seed)
            assert result.status.solved, (name, seed)
            smooth = shortcut_path(
                result.path, space, wall, planner.objective, ShortcutConfig(), seed
            )
            costs.append(path_metrics(smooth, space, wall.cost).avg_cost)
        avg[name] = np.mean(costs)
    assert avg["trrt"] < avg["rrt"]
