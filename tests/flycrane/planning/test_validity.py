"""The compiled validity checker against its references: numpy statics, fcl collisions and
the state space's discretization of each motion."""

from __future__ import annotations

import numpy as np

from flycrane.model.statics_kernel import configuration_cost
from flycrane.planning.problem import PlanningProblem
from flycrane.world.collision_kernel import collision_free


def reference_valid(problem: PlanningProblem, q: np.ndarray) -> np.ndarray:
    valid = np.isfinite(problem.validity.cost(q))
    valid[valid] = problem.validity.collision.collision_free(q[valid])
    return valid


def test_states_and_motions_match_the_references():
    problem = PlanningProblem.named("puzzle")
    rng = np.random.default_rng(3)
    q = problem.space.sample_uniform(rng, 1500)
    np.testing.assert_array_equal(problem.validity.is_valid(q), reference_valid(problem, q))
    # Short motions from valid configurations, both outcomes frequent.
    start = q[problem.validity.is_valid(q)][:150]
    end = start.copy()
    end[:, :3] += rng.normal(0, 0.4, (len(start), 3))
    end[:, 4] = np.clip(end[:, 4] + rng.normal(0, 0.1, len(start)), 0, None)
    end[:, 6:] += rng.normal(0, 0.1, (len(start), 3))
    fast = problem.validity.motions_are_valid(start, end)
    expected = [
        reference_valid(problem, problem.space.discretize(a, b, problem.validity.resolution)).all()
        for a, b in zip(start, end, strict=True)
    ]
    np.testing.assert_array_equal(fast, expected)
    assert 0.2 < np.mean(expected) < 0.8
    assert [problem.validity.motion_is_valid(a, b) for a, b in zip(start, end, strict=True)] == (
        expected
    )


def test_state_check_computes_the_pose_once_to_the_same_bits():
    """The state check computes R and the drones in the platform frame once for its statics
    and its collisions (flycrane.model.pose_kernel): the same bits as each part alone."""
    problem = PlanningProblem.named("puzzle")
    validity = problem.validity
    rng = np.random.default_rng(5)
    near = problem.start + rng.normal(0.0, 0.05, (1000, 9))
    near[:, 4] = np.abs(near[:, 4])
    q = np.concatenate([problem.space.sample_uniform(rng, 1000), near])
    cost, valid = validity.compiled.states(q, False, validity.work)
    np.testing.assert_array_equal(cost, configuration_cost(validity.system, q))
    free = collision_free(validity.system, validity.compiled.compiled_scene, q)
    np.testing.assert_array_equal(valid, np.isfinite(cost) & free)
    assert 0.2 < np.mean(valid) < 0.8


def test_is_safe_ignores_only_the_bounds():
    problem = PlanningProblem.named("rescue")
    q = np.array([0, 0, 10, 0, 0, 0, 1, 1, 1.0])  # above the roofs
    outside = q.copy()
    outside[4] = 0.1  # tilted beyond Rescue's max_tilt 0.08, still feasible and free
    assert not problem.validity.is_valid(outside)[0]
    assert problem.validity.is_safe(outside)[0]
    assert problem.validity.is_valid(q)[0] and problem.validity.is_safe(q)[0]
