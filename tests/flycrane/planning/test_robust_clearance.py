"""The bound on how much of a gap the drones' errors can close, against the gaps python-fcl
measures after drone errors solved by the exact direct kinematics."""

from __future__ import annotations

import numpy as np
import pytest

from flycrane.model.direct_kinematics import configuration_from_drone_positions
from flycrane.model.kinematics import drone_positions_from_configuration
from flycrane.planning.planners import PlannerOptions, plan
from flycrane.planning.problem import PlanningProblem
from flycrane.planning.robust_clearance import RobustClearance

#: The ``sitl`` position-error model's bounds [m]: common (horizontal, vertical) and each
#: drone's own about the three's mean (two thirds of the relative bounds).
COMMON, OWN = (0.04, 0.04), (0.02, 0.02 * 2 / 3)


@pytest.fixture(scope="module")
def near_slab():
    """The Puzzle's default path (seed 2), its six samples closest to an obstacle, and the
    checker of the real obstacles."""
    problem = PlanningProblem.named("puzzle")
    outcome = plan(
        problem.space, problem.validity, problem.start, problem.goal, PlannerOptions(seed=2)
    )
    real = problem.validity.with_clearance(0.0)
    samples = problem.space.discretize_path(outcome.path, 0.05)
    gaps = np.array([real.collision.clearance(q) for q in samples])
    return problem, real, samples[np.argsort(gaps)[:6]]


def test_the_bound_covers_drone_errors_solved_exactly_and_is_not_loose(near_slab):
    """Drone errors at the corners of the model's bounds (the worst a linear map reaches),
    solved exactly: no gap closes by more than its bound (plus the second-order term), and
    the worst one closes by at least half of it."""
    problem, real, samples = near_slab
    robust = RobustClearance(real, COMMON, OWN)
    gap, bound = robust.gaps(samples)
    assert np.all(bound > 0) and np.all(gap <= robust.near)
    rng = np.random.default_rng(7)
    worst = []
    for q, g, b in zip(samples, gap, bound, strict=True):
        drones = drone_positions_from_configuration(problem.system, q)[0]
        angle = rng.uniform(0, 2 * np.pi, (200, 3))
        own = np.stack(
            [OWN[0] * np.cos(angle), OWN[0] * np.sin(angle),
             OWN[1] * rng.choice([-1.0, 1.0], (200, 3))], axis=-1,
        )  # fmt: skip
        direction = rng.normal(size=(200, 1, 3))
        common = direction / np.linalg.norm(direction, axis=-1, keepdims=True) * COMMON[0]
        solved = configuration_from_drone_positions(
            problem.system, drones[None] + own + common, initial=np.repeat(q[None], 200, 0)
        )
        moved = solved.q[solved.converged]
        lost = g - np.array([real.collision.clearance(m) for m in moved])
        assert np.all(lost <= b * 1.05 + 2e-3), (lost.max(), b)
        worst.append(lost.max() / b)
    assert np.median(worst) > 0.5, worst


def test_farther_than_near_there_is_no_bound(near_slab):
    problem, real, _ = near_slab
    robust = RobustClearance(real, COMMON, OWN, near=0.05)
    high = problem.start.copy()
    high[2] += 1.0
    gap, bound = robust.gaps(high)
    assert gap[0] > 0.05 and bound[0] == 0.0
    assert robust.margin(np.stack([high, high]), problem.space) == np.inf
