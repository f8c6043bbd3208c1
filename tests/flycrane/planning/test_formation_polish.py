"""The formation polish: what it may change, what it must keep, and how far it gets.

Margins are measured with the numpy statics (:func:`flycrane.model.statics.evaluate_statics`),
not the compiled kernel the polish optimizes with, on the path discretized at the metrics
resolution; the optimum it reaches is held against a brute-force grid over the alphas.
"""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from flycrane.errors import InputError
from flycrane.model.statics import evaluate_statics
from flycrane.planning.formation_polish import PolishConfig, polish_formation
from flycrane.planning.metrics import METRICS_RESOLUTION
from flycrane.planning.planners import PlannerOptions, plan
from flycrane.planning.problem import PlanningProblem


def least_margins(problem: PlanningProblem, path: np.ndarray) -> tuple[float, float, float, float]:
    """(slack, headroom, thrust, largest cost) along the discretized path."""
    samples = problem.space.discretize_path(path, METRICS_RESOLUTION)
    report = evaluate_statics(problem.system, samples)
    return (
        float(report.slack_margin.min()),
        float(report.overload_margin.min()),
        float(report.thrust_margin.min()),
        float(problem.validity.cost(samples).max()),
    )


@pytest.fixture(scope="module")
def puzzle() -> PlanningProblem:
    return PlanningProblem.named("puzzle")


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_bitrrt_paths_gain_margins_and_keep_every_other_bound(puzzle, seed):
    options = PlannerOptions(algorithm="bitrrt", seed=seed, time_budget=300, polish=False)
    path = plan(puzzle.space, puzzle.validity, puzzle.start, puzzle.goal, options).path
    config = PolishConfig()
    polished = polish_formation(path, puzzle.space, puzzle.validity, puzzle.system, config)

    # Only the formation moves, and by little: same waypoints, same platform poses, same
    # end points, every alpha within reach of the planner's.
    assert polished.shape == path.shape
    np.testing.assert_array_equal(polished[:, :6], path[:, :6])
    np.testing.assert_array_equal(polished[[0, -1]], path[[0, -1]])
    assert np.abs(polished[:, 6:] - path[:, 6:]).max() <= config.reach + 1e-12
    for a, b in itertools.pairwise(polished):
        assert puzzle.validity.motion_is_valid(a, b)

    slack, headroom, thrust, cost = least_margins(puzzle, path)
    new_slack, new_headroom, new_thrust, new_cost = least_margins(puzzle, polished)
    assert new_slack >= slack
    assert new_headroom >= headroom
    assert new_thrust >= thrust
    assert new_cost <= cost
    # Measured on these seeds: thrust margin + headroom +0.4 to +1.9 N.
    assert new_thrust + new_headroom >= thrust + headroom + 0.2


def test_polish_reaches_the_best_formation_of_a_brute_force_grid():
    """One waypoint between two hovers, tilted and squeezed: the polish's least thrust
    margin plus headroom is at least the best of an 11^3 grid over its alphas (within the
    polish's reach) that keeps every least margin and the largest cost."""
    problem = PlanningProblem.named("rescue_broad")  # open air at 12 m, tilt up to 0.6 rad
    space = problem.space
    start = np.array([0.0, 0.0, 12.0, 0.0, 0.0, 0.0, 1.0, 1.0, 1.0])
    goal = np.array([4.0, 0.0, 12.0, 0.0, 0.0, 0.0, 1.0, 1.0, 1.0])
    middle = np.array([2.0, 0.0, 12.5, 0.3, 0.35, 0.2, 0.45, 0.45, 0.45])
    path = np.stack([start, middle, goal])
    slack, headroom, thrust, cost = least_margins(problem, path)
    assert np.isfinite(cost)
    config = PolishConfig()

    best = -np.inf
    offsets = np.linspace(-config.reach, config.reach, 11)
    for alphas in itertools.product(*(np.clip(a + offsets, space.alpha_low, space.alpha_high)
                                      for a in middle[6:])):  # fmt: skip
        q = middle.copy()
        q[6:] = alphas
        s, h, t, c = least_margins(problem, np.stack([start, q, goal]))
        if s >= slack and h >= headroom and t >= thrust and c <= cost:
            best = max(best, t + h)

    polished = polish_formation(path, space, problem.validity, problem.system, config)
    new_slack, new_headroom, new_thrust, new_cost = least_margins(problem, polished)
    assert new_slack >= slack and new_headroom >= headroom and new_cost <= cost
    assert new_thrust + new_headroom >= best


def test_bitrrt_paths_are_polished_unless_asked_not_to_be(puzzle):
    """The polish is bitrrt's (its paths are judged with it: BENCHMARKS.md "Planner v2");
    the paper's T-RRT stays as the paper has it unless asked."""
    assert PlannerOptions().polishes("bitrrt") and not PlannerOptions().polishes("trrt")
    assert PlannerOptions(polish=True).polishes("trrt")
    options = PlannerOptions(algorithm="bitrrt", seed=0, time_budget=300)
    polished = plan(puzzle.space, puzzle.validity, puzzle.start, puzzle.goal, options)
    unpolished = plan(
        puzzle.space,
        puzzle.validity,
        puzzle.start,
        puzzle.goal,
        options.model_copy(update={"polish": False}),
    )
    np.testing.assert_array_equal(polished.path[:, :6], unpolished.path[:, :6])
    assert not np.array_equal(polished.path, unpolished.path)


@pytest.mark.parametrize(
    ("field", "value"),
    [
        ("passes", -1),
        ("evaluations", 0),
        ("softness", 0.0),
        ("resolution", -1.0),
        ("band", -0.1),
        ("reach", -0.1),
    ],
)
def test_bad_options_name_the_field(field, value):
    with pytest.raises(InputError) as error:
        PolishConfig(**{field: value})
    assert field in str(error.value)
