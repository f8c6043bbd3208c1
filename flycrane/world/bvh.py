"""A bounding-volume hierarchy over a scene's obstacles, for the compiled collision checks.

A site given as triangle meshes has thousands of faces; testing every robot body's box
against each of them is linear in the faces. The hierarchy is a binary tree of
axis-aligned boxes built once per scene (top down: split the shapes at the median of their
box centres along the axis where those centres spread most, until at most
:data:`LEAF_SIZE` remain), so that a body's box visits only the branches it overlaps:
logarithmic in the faces for a body near a few of them. As in fcl's BVH, each node's box
bounds the boxes of everything below it, so no overlapping shape is ever skipped.

The tree is plain arrays (numba reads them): node ``m`` has its box ``low[m]``,
``high[m]``; a leaf (``count[m] > 0``) holds shapes ``order[first[m]:first[m] + count[m]]``,
an inner node its children ``first[m]`` and ``first[m] + 1``. Node 0 is the root; a scene
without obstacles has no node.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

#: Most shapes in a leaf: below this, testing them beats descending further.
LEAF_SIZE = 4
#: Nodes :func:`traversal stacks <stack>` can hold: twice the deepest tree a median split
#: makes of any scene the bounds allow, with room to spare.
STACK_SIZE = 128


@dataclass(frozen=True)
class Hierarchy:
    """The tree's arrays (module docstring)."""

    low: NDArray[np.float64]  #: (M, 3)
    high: NDArray[np.float64]  #: (M, 3)
    first: NDArray[np.int64]  #: (M,)
    count: NDArray[np.int64]  #: (M,) 0 for inner nodes
    order: NDArray[np.int64]  #: (O,) shape indices, leaf by leaf

    def arrays(self) -> tuple[NDArray, ...]:
        return self.low, self.high, self.first, self.count, self.order


def build_hierarchy(low: NDArray[np.float64], high: NDArray[np.float64]) -> Hierarchy:
    """The hierarchy of shapes with boxes ``low``, ``high`` (O, 3) each (module docstring).

    Built a level at a time, each level's boxes and splits in a few array operations (a
    mesh of a million faces in seconds, where a node at a time took a minute): the tree is
    the one the depth-first build makes, node for node (:func:`_levels` numbers the nodes
    as it does), every array equal to its bit.
    """
    low, high = np.asarray(low, dtype=float).reshape(-1, 3), np.asarray(high, float).reshape(-1, 3)
    if not len(low):
        empty = np.zeros((0, 3))
        none = np.zeros(0, dtype=np.int64)
        return Hierarchy(empty, empty.copy(), none, none.copy(), none.copy())
    shapes = len(low)
    levels, first, count = _levels(shapes)
    order = np.arange(shapes, dtype=np.int64)
    # the shapes' bounds and centres at their places in ``order``, moved with them
    at_low, at_high, at_centre = low.copy(), high.copy(), (low + high) / 2
    signed_zeros = bool(_negative_zero(low).any() or _negative_zero(high).any())
    nodes_low = np.empty((len(first), 3))
    nodes_high = np.empty((len(first), 3))
    for ids, begin, end in levels:  # nodes by their first place, a level at a time
        # each node's box, from its shapes as its parent's split left them
        ends = np.stack([begin, end], axis=1).reshape(-1)
        ends = ends[:-1] if ends[-1] == shapes else ends  # the last node's runs to the end
        nodes_low[ids] = np.minimum.reduceat(at_low, ends)[::2]
        nodes_high[ids] = np.maximum.reduceat(at_high, ends)[::2]
        if signed_zeros:
            _zero_bounds(
                ids, begin, end, ends, order, (low, high), (at_low, at_high), nodes_low, nodes_high
            )
        inner = end - begin > LEAF_SIZE  # then split the nodes of more than a leaf
        if not inner.any():
            continue
        index, starts, segment = _ranges(begin[inner], end[inner])
        middle = np.take(at_centre, index, axis=0)  # (np.take: many times faster than [])
        spread = np.maximum.reduceat(middle, starts) - np.minimum.reduceat(middle, starts)
        axis = np.argmax(spread, axis=1)  # where the centres spread most (the first of ties)
        key = np.take(middle.reshape(-1), 3 * np.arange(len(index)) + axis[segment])
        moved = np.arange(shapes)
        moved[index] = np.take(index, _stable_order(segment, key))
        order = np.take(order, moved)
        at_low, at_high, at_centre = (
            np.take(a, moved, axis=0) for a in (at_low, at_high, at_centre)
        )
    return Hierarchy(nodes_low, nodes_high, first, count, order)


def _negative_zero(values: NDArray[np.float64]) -> NDArray[np.bool_]:
    return (values == 0.0) & np.signbit(values)


def _zero_bounds(ids, begin, end, ends, order, bounds, at_bounds, nodes_low, nodes_high) -> None:
    """Where a node's bound is a zero and its shapes' bounds there include -0.0: which zero
    numpy's smallest and largest give depends on how many values they reduce at once, so
    such a node's box is taken as the depth-first build took it (``.min(axis=0)`` of its
    shapes' bounds in their order), to the sign of its zeros."""
    low, high = bounds
    negative = [np.logical_or.reduceat(_negative_zero(a), ends)[::2] for a in at_bounds]
    zero = (negative[0] & (nodes_low[ids] == 0.0)) | (negative[1] & (nodes_high[ids] == 0.0))
    for j in np.flatnonzero(zero.any(axis=1)):
        members = order[begin[j] : end[j]]
        nodes_low[ids[j]] = low[members].min(axis=0)
        nodes_high[ids[j]] = high[members].max(axis=0)


def _stable_order(segment: NDArray[np.int64], key: NDArray[np.float64]) -> NDArray[np.int64]:
    """The permutation that sorts positions by ``segment`` (ascending, each one's positions
    together), then ``key``, then position: as ``np.argsort(key, kind="stable")`` within each
    segment. One sort of unique integers where they fit in 63 bits, two stable sorts else."""
    size = len(key)
    by_key = np.argsort(key)
    ordered = key[by_key]
    rank = np.empty(size, dtype=np.int64)  # equal keys (0.0 and -0.0 too) share a rank
    rank[by_key] = np.cumsum(np.concatenate([[True], ordered[1:] != ordered[:-1]])) - 1
    ranks = int(rank[by_key[-1]]) + 1
    if (int(segment[-1]) + 1) * ranks * size < 2**63:
        return np.argsort((segment * ranks + rank) * size + np.arange(size))
    by_key = np.argsort(key, kind="stable")
    return by_key[np.argsort(segment[by_key], kind="stable")]


def _ranges(begin: NDArray[np.int64], end: NDArray[np.int64]) -> tuple[NDArray, ...]:
    """The positions ``begin[j]:end[j]`` (each non-empty) one range after another, where
    each range starts among them, and the range of each."""
    sizes = end - begin
    starts = np.cumsum(sizes) - sizes
    segment = np.repeat(np.arange(len(sizes)), sizes)
    index = np.arange(int(sizes.sum()), dtype=np.int64) + (begin - starts)[segment]
    return index, starts, segment


def _levels(shapes: int) -> tuple[list[tuple[NDArray, NDArray, NDArray]], NDArray, NDArray]:
    """The tree of ``shapes`` (> 0) shapes as a depth-first build makes it, whatever the
    shapes: per level, its nodes (numbers, first and end places in ``order``, by first
    place); and per node, ``first`` and ``count`` (module docstring).

    The build splits the positions ``begin:end`` of every node of more than
    :data:`LEAF_SIZE` shapes at ``(begin + end) // 2`` and takes the nodes to split from a
    stack, the second child first; the k-th node it splits gets the numbers 2 k + 1 and
    2 k + 2 for its children, and a node's place in that order follows from the sizes of the
    nodes before it.
    """
    splits: dict[int, int] = {}

    def inner(size: int) -> int:  # the nodes a node of this size splits, itself included
        if size <= LEAF_SIZE:
            return 0
        if size not in splits:
            splits[size] = 1 + inner(size // 2) + inner(size - size // 2)
        return splits[size]

    total = 1 + 2 * inner(shapes)
    first = np.empty(total, dtype=np.int64)
    count = np.empty(total, dtype=np.int64)
    levels = []
    ids, begin, end = np.zeros(1, np.int64), np.zeros(1, np.int64), np.full(1, shapes, np.int64)
    rank = np.zeros(1, np.int64)  # of the split nodes, where each node is split
    while len(ids):
        by_place = np.argsort(begin)
        ids, begin, end, rank = ids[by_place], begin[by_place], end[by_place], rank[by_place]
        levels.append((ids, begin, end))
        size = end - begin
        leaf = size <= LEAF_SIZE
        first[ids[leaf]], count[ids[leaf]] = begin[leaf], size[leaf]
        split = ~leaf
        ids, begin, end, rank = ids[split], begin[split], end[split], rank[split]
        first[ids], count[ids] = 2 * rank + 1, 0
        middle = (begin + end) // 2
        sizes, which = np.unique(end - middle, return_inverse=True)  # a few sizes a level
        second = np.array([inner(int(s)) for s in sizes], dtype=np.int64)[which.reshape(-1)]
        ids = np.concatenate([2 * rank + 1, 2 * rank + 2])
        begin, end = np.concatenate([begin, middle]), np.concatenate([middle, end])
        rank = np.concatenate([rank + 1 + second, rank + 1])
    return levels, first, count


def stack() -> NDArray[np.int64]:
    """Scratch for one traversal (kept in a checker's workspace: nothing is allocated per
    configuration)."""
    return np.zeros(STACK_SIZE, dtype=np.int64)
