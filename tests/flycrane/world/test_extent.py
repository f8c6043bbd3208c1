"""The corridor's least width (benchmarks/corridor_width.py, issue 12) against the checker.

Independent evidence: the validity checker (compiled kernel and python-fcl) decides whether
a configuration fits walls placed where :mod:`flycrane.world.extent` says its bodies end.
"""

from __future__ import annotations

import numpy as np
import pytest

from benchmarks.corridor_width import WidthSearch, centred, corridor_gap, corridor_with_gap
from flycrane.errors import InputError
from flycrane.planning.problem import PlanningProblem
from flycrane.planning.validity import ValidityChecker
from flycrane.world.extent import extent_from_configuration, width_from_configuration
from flycrane.world.scene import SceneSpec

#: BENCHMARKS.md, "Corridor: the least width at which the formation fits": w* [m].
W_STAR = 1.6250


@pytest.fixture(scope="module")
def problem() -> PlanningProblem:
    return PlanningProblem.named("corridor")


def checker(scene: SceneSpec) -> ValidityChecker:
    return PlanningProblem.from_scene(scene).validity


@pytest.fixture(scope="module")
def feasible(problem: PlanningProblem) -> np.ndarray:
    """300 configurations uniform in the bounds that are feasible and free of
    self-collision and the ground (by the checker without the walls), at x = 0."""
    rng = np.random.default_rng(12)
    q = problem.space.sample_uniform(rng, 5000)
    q[:, 0] = 0.0  # between the walls, which span x in [-5, 5]
    q[:, 2] = rng.uniform(3.0, 8.0, len(q))  # clear of the ground and the bounds' top
    q = q[problem.validity.without(["north wall", "south wall"]).is_valid(q)]
    assert len(q) >= 300
    return q[:300]


def test_script_configuration_fits_a_corridor_one_cm_wider_than_w_star(problem):
    found, limit = WidthSearch(problem).least_width(seed=0)
    assert limit.width == pytest.approx(W_STAR, abs=5e-4)
    assert limit.cost == np.inf  # w* is an infimum: slack margins reach 0 there
    assert np.isfinite(found.cost) and found.width - limit.width < 1e-3
    q = centred(problem, found.q)
    assert checker(corridor_with_gap(problem.scene, limit.width + 0.01)).is_valid(q)[0]
    assert not checker(corridor_with_gap(problem.scene, limit.width - 0.01)).is_valid(q)[0]


def test_width_agrees_with_the_checker_in_corridors_two_cm_either_side(problem, feasible):
    widths = width_from_configuration(problem.system, problem.scene, feasible)
    placed = centred(problem, feasible)
    for q, w in zip(placed, widths, strict=True):
        wide = checker(corridor_with_gap(problem.scene, w + 0.02))
        tight = checker(corridor_with_gap(problem.scene, w - 0.02))
        assert wide.is_valid(q)[0], (q, w)
        assert not tight.is_valid(q)[0], (q, w)


@pytest.mark.parametrize("wall", ["south wall", "north wall"])
def test_each_side_of_the_extent_is_where_the_checker_finds_the_wall(problem, feasible, wall):
    """One wall at a time, the configuration moved to 1 mm inside or outside of its face."""
    half_gap = corridor_gap(problem.scene) / 2
    face = half_gap if wall == "north wall" else -half_gap
    other = "south wall" if wall == "north wall" else "north wall"
    one_wall = checker(problem.scene.without([other]))
    extent = extent_from_configuration(problem.system, problem.scene, feasible)
    side = extent[:, 1] if wall == "north wall" else extent[:, 0]
    inward = -np.sign(face)
    for offset, expected in ((1e-3, True), (-1e-3, False)):
        q = feasible.copy()
        q[:, 1] += face - side + inward * offset
        assert np.all(one_wall.is_valid(q) == expected), offset


def test_lowest_point_is_where_the_checker_finds_the_ground(problem, feasible):
    """The lowest point of the bodies (along z) against the ground z = 0."""
    extent = extent_from_configuration(problem.system, problem.scene, feasible, (0.0, 0.0, 1.0))
    free = problem.validity.without(["north wall", "south wall"])
    for offset, expected in ((1e-3, True), (-1e-3, False)):
        q = feasible.copy()
        q[:, 2] += offset - extent[:, 0]
        assert np.all(free.is_valid(q) == expected), offset


@pytest.mark.parametrize("direction", [(0.0, 0.0, 0.0), (1.0, 0.0), (np.nan, 0.0, 1.0)])
def test_a_direction_that_is_not_a_finite_non_zero_vector_is_refused(problem, direction):
    with pytest.raises(InputError, match="direction"):
        width_from_configuration(problem.system, problem.scene, problem.start, direction)
