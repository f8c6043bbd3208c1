"""Exact nearest-neighbour queries of a growing tree: a hashed grid over node positions.

The metric's embedding (:meth:`ConfigurationSpace.embed`) starts with the platform position
unscaled, so the distance between two configurations is at least the distance between
their positions. Nodes are filed in cubic cells of side ``cell`` by position (a hash table
of chained buckets, so the grid needs no bounds and grows with the tree). A query visits
the cells in rings of growing Chebyshev radius k around its own cell; every node not yet
visited lies more than k * cell away in position, so once the best distance found is at
most k * cell the answer is exact. Where the rings would visit more cells than the tree has
nodes (a query far from a small tree), a brute-force scan is cheaper and is done instead.

Brute force costs O(n) per query (tens of microseconds at tens of thousands of nodes:
BENCHMARKS.md, "Moved from code comments"), and a planner queries once or twice per
expansion attempt; the grid keeps a query at a few microseconds where the tree is dense
around the query, as it is for local samples.
"""

from __future__ import annotations

import math

from flycrane.kernels import kernel

#: Width of the embedding (position 3, scaled rotation matrix 9, alpha chords 6).
EMBEDDING = 18
#: Buckets of the hash table (a power of two); chains absorb any excess of cells.
TABLE_SIZE = 1 << 16


@kernel()
def _bucket(x: int, y: int, z: int) -> int:
    # Teschner et al.'s spatial hash (large primes, XOR), masked to the table.
    return ((x * 73856093) ^ (y * 19349663) ^ (z * 83492791)) & (TABLE_SIZE - 1)


@kernel()
def _squared_distance(embeddings, row, point, bound) -> float:
    """|embeddings[row] - point|^2, or the position's part alone where that reaches
    ``bound`` (the row cannot be the nearest then; most rows a grid query meets are far in
    position), the rest summed without a test per term."""
    total = 0.0
    for a in range(3):
        d = embeddings[row, a] - point[a]
        total += d * d
    if total >= bound:
        return total
    for a in range(3, EMBEDDING):
        d = embeddings[row, a] - point[a]
        total += d * d
    return total


@kernel()
def brute_nearest(embeddings, count, point) -> tuple[int, float]:
    """Index of the row of embeddings[:count] nearest to point (18,), and the distance."""
    best, index = math.inf, -1
    for row in range(count):
        total = _squared_distance(embeddings, row, point, best)
        if total < best:
            best, index = total, row
    return index, math.sqrt(best)


@kernel()
def grid_insert(head, chain, cells, index, point, cell) -> None:
    """File node ``index`` (embedding ``point``) in its cell."""
    x = math.floor(point[0] / cell)
    y = math.floor(point[1] / cell)
    z = math.floor(point[2] / cell)
    cells[index, 0], cells[index, 1], cells[index, 2] = x, y, z
    bucket = _bucket(x, y, z)
    chain[index] = head[bucket]
    head[bucket] = index


@kernel()
def grid_nearest(head, chain, cells, embeddings, count, point, cell) -> tuple[int, float]:
    """The exact nearest node to ``point`` (18,) among the first ``count`` (module
    docstring): (index, distance)."""
    cx = math.floor(point[0] / cell)
    cy = math.floor(point[1] / cell)
    cz = math.floor(point[2] / cell)
    best, index = math.inf, -1
    visited = 0
    k = 0
    while True:
        for dx in range(-k, k + 1):
            for dy in range(-k, k + 1):
                shell = abs(dx) == k or abs(dy) == k
                dz = -k
                while dz <= k:
                    x, y, z = cx + dx, cy + dy, cz + dz
                    node = head[_bucket(x, y, z)]
                    while node >= 0:
                        if cells[node, 0] == x and cells[node, 1] == y and cells[node, 2] == z:
                            total = _squared_distance(embeddings, node, point, best)
                            if total < best:
                                best, index = total, node
                        node = chain[node]
                    visited += 1
                    # Inside the shell's faces only the two z ends are on ring k.
                    dz += 1 if shell or k == 0 else 2 * k
        if index >= 0 and math.sqrt(best) <= k * cell:
            return index, math.sqrt(best)
        k += 1
        if visited + (2 * k + 1) ** 2 * 6 > count:
            return brute_nearest(embeddings, count, point)
