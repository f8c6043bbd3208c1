"""The search tree of RRT-family planners: nodes, parents, costs, nearest neighbours.

Nodes live in growing numpy arrays (capacity doubles), so the nearest-neighbour query is one
vectorized distance computation in the state space's embedding. Brute force is the right
tool at our tree sizes (thousands of nodes, 18-wide embedding: tens of microseconds per
query) and is exact.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from flycrane.planning.state_space import EMBEDDING_SIZE, ConfigurationSpace


def path_from_root(q: NDArray[np.float64], parent: NDArray[np.int64], index: int) -> NDArray:
    """Configurations ``q`` from the root (parent -1) to node ``index``, shape (M, 9)."""
    chain = []
    while index >= 0:
        chain.append(index)
        index = int(parent[index])
    return q[chain[::-1]].copy()


class Tree:
    """A rooted tree of configurations with their costs."""

    def __init__(self, space: ConfigurationSpace, capacity: int = 1024) -> None:
        self.space = space
        self.size = 0
        self.refinement_nodes = 0  #: nodes closer to their parent than the extension step
        self.cost_low = np.inf  #: lowest node cost
        self.cost_high = -np.inf  #: highest node cost
        self.q = np.empty((capacity, 9))
        self.embedding = np.empty((capacity, EMBEDDING_SIZE))
        self.parent = np.empty(capacity, dtype=np.int64)
        self.cost = np.empty(capacity)

    def add(self, q: NDArray, parent: int, cost: float, refinement: bool = False) -> int:
        """Append a node; returns its index. ``parent`` is -1 for the root."""
        if self.size == len(self.q):
            grow = len(self.q)
            self.q = np.concatenate([self.q, np.empty((grow, 9))])
            self.embedding = np.concatenate([self.embedding, np.empty((grow, EMBEDDING_SIZE))])
            self.parent = np.concatenate([self.parent, np.empty(grow, dtype=np.int64)])
            self.cost = np.concatenate([self.cost, np.empty(grow)])
        index = self.size
        self.q[index] = q
        self.embedding[index] = self.space.embed(q)[0]
        self.parent[index] = parent
        self.cost[index] = cost
        self.refinement_nodes += bool(refinement)
        self.cost_low, self.cost_high = min(self.cost_low, cost), max(self.cost_high, cost)
        self.size += 1
        return index

    def nearest(self, embedding: NDArray) -> tuple[int, float]:
        """Index of the node nearest to an embedded configuration (18,), and the distance."""
        delta = self.embedding[: self.size] - embedding
        squared = np.einsum("ij,ij->i", delta, delta)
        index = int(np.argmin(squared))
        return index, float(np.sqrt(squared[index]))

    def cost_range(self) -> float:
        """Highest minus lowest node cost (costRange of the paper's Algorithm 2)."""
        return float(self.cost_high - self.cost_low)

    def path_to(self, index: int) -> NDArray[np.float64]:
        """Configurations from the root to node ``index``, shape (M, 9)."""
        return path_from_root(self.q, self.parent, index)
