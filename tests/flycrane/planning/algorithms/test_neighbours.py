"""The grid nearest-neighbour index answers exactly what a brute-force scan answers."""

from __future__ import annotations

import numpy as np
import pytest

from flycrane.planning.algorithms.neighbours import TABLE_SIZE, grid_insert, grid_nearest
from flycrane.planning.problem import PlanningProblem


class Grid:
    """One tree's index arrays, as the planner's Forest holds them per tree."""

    def __init__(self, cell: float, size: int) -> None:
        self.cell = cell
        self.head = np.full(TABLE_SIZE, -1, dtype=np.int64)
        self.chain = np.empty(size, dtype=np.int64)
        self.cells = np.empty((size, 3), dtype=np.int64)

    def insert(self, index: int, point: np.ndarray) -> None:
        grid_insert(self.head, self.chain, self.cells, index, point, self.cell)

    def nearest(self, embeddings: np.ndarray, count: int, point: np.ndarray):
        return grid_nearest(self.head, self.chain, self.cells, embeddings, count, point, self.cell)


def brute_force(embeddings: np.ndarray, point: np.ndarray) -> float:
    return float(np.sqrt(((embeddings - point) ** 2).sum(axis=1)).min())


@pytest.mark.parametrize("cell", [0.1, 0.5, 2.0])
def test_grid_nearest_is_the_brute_force_nearest(cell):
    """Trees as the planner builds them (configurations embedded by the state space),
    queried near their nodes, far from them and across the cells' sign boundaries."""
    problem = PlanningProblem.named("puzzle_broad")
    rng = np.random.default_rng(7)
    for size in (1, 7, 400, 3000):
        q = problem.space.sample_uniform(rng, size)
        q[: size // 2, :3] = rng.normal(0.0, 0.4, (size // 2, 3))  # a dense cluster at 0
        embeddings = np.ascontiguousarray(problem.space.embed(q))
        index = Grid(cell, size)
        for i, point in enumerate(embeddings):
            index.insert(i, point)
        queries = np.concatenate(
            [
                problem.space.embed(problem.space.sample_uniform(rng, 100)),
                embeddings[rng.integers(0, size, 100)] + rng.normal(0.0, 0.2, (100, 18)),
                embeddings[rng.integers(0, size, 20)],  # exactly on nodes
            ]
        )
        for point in queries:
            found, distance = index.nearest(embeddings, size, np.ascontiguousarray(point))
            expected = brute_force(embeddings, point)
            assert distance == pytest.approx(expected, abs=1e-12)
            assert np.linalg.norm(embeddings[found] - point) == pytest.approx(expected, abs=1e-12)


def test_far_queries_fall_back_to_the_scan_and_stay_exact():
    """A query far from a small tree would visit more cells than the tree has nodes."""
    rng = np.random.default_rng(1)
    embeddings = rng.normal(0.0, 0.3, (50, 18))
    index = Grid(0.05, len(embeddings))
    for i, point in enumerate(embeddings):
        index.insert(i, point)
    for point in rng.normal(0.0, 30.0, (50, 18)):
        _, distance = index.nearest(embeddings, len(embeddings), point)
        assert distance == pytest.approx(brute_force(embeddings, point), abs=1e-12)
