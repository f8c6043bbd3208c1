"""The anytime refinement: what it must keep, what it must lower, and when it stops.

Evidence independent of the code under test: every configuration along the refined path,
at the checker's resolution, is checked with python-fcl (the collision reference) and the
numpy statics (the cost's reference); avgC comes from the path metrics and the margins from
the numpy statics on the path resampled at the metrics resolution.
"""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from flycrane.errors import InputError
from flycrane.model.cost import cost_from_report
from flycrane.model.statics import evaluate_statics
from flycrane.planning.metrics import METRICS_RESOLUTION, path_metrics
from flycrane.planning.planners import PlannerOptions, plan
from flycrane.planning.problem import PlanningProblem
from flycrane.planning.refinement import MARGIN_TOLERANCE, RefinementConfig, refine_path
from flycrane.planning.result import TerminationCondition
from flycrane.planning.robust_clearance import RobustClearance

#: Generous: a refinement of these paths converges in about a second.
BUDGET = 30.0


@pytest.fixture(scope="module", params=[("rescue", 1), ("puzzle", 2)], ids=["rescue", "puzzle"])
def case(request) -> tuple[PlanningProblem, np.ndarray, int]:
    """(problem, the default planner's smoothed and polished path, seed)."""
    scene, seed = request.param
    problem = PlanningProblem.named(scene)
    options = PlannerOptions(seed=seed, time_budget=60.0, improve_time=0.0)
    outcome = plan(problem.space, problem.validity, problem.start, problem.goal, options)
    assert outcome.result.status.solved
    return problem, outcome.path, seed


def refine(problem: PlanningProblem, path: np.ndarray, seed: int, termination=None):
    return refine_path(
        path,
        problem.space,
        problem.validity,
        problem.system,
        RefinementConfig(),
        termination or TerminationCondition(BUDGET),
        seed=seed,
    )


@pytest.fixture(scope="module")
def refined(case) -> np.ndarray:
    problem, path, seed = case
    return refine(problem, path, seed)


def least_margins(problem: PlanningProblem, path: np.ndarray) -> np.ndarray:
    """(slack, headroom, thrust) [N] and the largest cost along the resampled path."""
    samples = problem.space.discretize_path(path, METRICS_RESOLUTION)
    report = evaluate_statics(problem.system, samples)
    return np.array(
        [
            report.slack_margin.min(),
            report.overload_margin.min(),
            report.thrust_margin.min(),
            -cost_from_report(problem.system, report).max(),
        ]
    )


def test_refined_path_is_valid_everywhere(case, refined):
    problem, _, _ = case
    validity = problem.validity
    for a, b in itertools.pairwise(refined):
        q = problem.space.discretize(a, b, validity.resolution)
        assert validity.collision.collision_free(q).all()
        assert np.isfinite(
            cost_from_report(problem.system, evaluate_statics(problem.system, q))
        ).all()
        assert problem.space.contains(q).all()


def test_same_ends_lower_avgc_and_no_margin_lost(case, refined):
    problem, path, _ = case
    np.testing.assert_array_equal(refined[[0, -1]], path[[0, -1]])
    before = path_metrics(path, problem.space, problem.validity.cost)
    after = path_metrics(refined, problem.space, problem.validity.cost)
    # Not only never above: these paths have far to go (BENCHMARKS.md, "Anytime improvement").
    assert after.avg_cost < 0.7 * before.avg_cost
    # The guard against buying avgC with length: the cost integral does not rise either.
    assert after.cost_integral <= before.cost_integral
    # The least margins and (negated) the largest cost, at the metrics resolution.
    assert np.all(least_margins(problem, refined) >= least_margins(problem, path) - 1e-9)


def test_same_seed_same_path(case, refined):
    problem, path, seed = case
    np.testing.assert_array_equal(refine(problem, path, seed), refined)


def test_an_expired_termination_returns_the_input(case):
    problem, path, seed = case
    expired = TerminationCondition(0.0)
    np.testing.assert_array_equal(refine(problem, path, seed, expired), path)
    cancelled = TerminationCondition(BUDGET, should_stop=lambda: True)
    np.testing.assert_array_equal(refine(problem, path, seed, cancelled), path)


def test_stopped_midway_the_path_is_valid_and_no_worse(case):
    """A cancel after a few phases: what has been done so far, still valid and not worse."""
    problem, path, seed = case
    polls = itertools.count()
    termination = TerminationCondition(BUDGET, should_stop=lambda: next(polls) >= 8)
    partial = refine(problem, path, seed, termination)
    for a, b in itertools.pairwise(partial):
        assert problem.validity.motion_is_valid(a, b)
    before = path_metrics(path, problem.space, problem.validity.cost)
    assert path_metrics(partial, problem.space, problem.validity.cost).avg_cost <= before.avg_cost


def test_plan_refines_within_its_improve_time_only_when_asked():
    problem = PlanningProblem.named("rescue")
    outcomes = [
        plan(
            problem.space,
            problem.validity,
            problem.start,
            problem.goal,
            PlannerOptions(seed=0, improve_time=improve),
        )
        for improve in (0.0, 5.0)
    ]
    off, on = (o.metrics for o in outcomes)
    assert off is not None and on is not None
    assert on.avg_cost < off.avg_cost


def test_options_are_checked():
    with pytest.raises(InputError, match="finest"):
        RefinementConfig(finest=1.0, spacing=0.5)
    with pytest.raises(InputError, match="shortcuts"):
        RefinementConfig(shortcuts=-1)
    with pytest.raises(ValueError, match="improve_time"):
        PlannerOptions(improve_time=-1.0)


def test_the_robust_margin_is_kept_where_it_would_be_lost(case, refined):
    """Given the drones' errors, the refined path keeps the input's robust margin (or
    zero, the lower) and still lowers avgC; on the Puzzle (seed 2) the refinement without
    them passes the slab in a pose the errors turn further, and loses it."""
    problem, path, seed = case
    common, own = (0.04, 0.04), (0.02, 0.02 * 2 / 3)  # the ``sitl`` model's
    robust = RobustClearance(problem.validity.with_clearance(0.0), common, own)
    guarded = refine_path(
        path,
        problem.space,
        problem.validity,
        problem.system,
        RefinementConfig(),
        TerminationCondition(BUDGET),
        seed=seed,
        robust=robust,
    )
    floor = min(robust.margin(path, problem.space), 0.0) - MARGIN_TOLERANCE
    assert robust.margin(guarded, problem.space) >= floor
    cost = problem.validity.cost
    before = path_metrics(path, problem.space, cost).avg_cost
    assert path_metrics(guarded, problem.space, cost).avg_cost < 0.8 * before
    if problem.scene.name == "puzzle":
        assert robust.margin(refined, problem.space) < floor - 0.01
