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
    """The hierarchy of shapes with boxes ``low``, ``high`` (O, 3) each (module docstring)."""
    low, high = np.asarray(low, dtype=float).reshape(-1, 3), np.asarray(high, float).reshape(-1, 3)
    centres = (low + high) / 2
    nodes_low: list[NDArray] = []
    nodes_high: list[NDArray] = []
    first: list[int] = []
    count: list[int] = []
    order = np.arange(len(low))
    if not len(low):
        empty = np.zeros((0, 3))
        none = np.zeros(0, dtype=np.int64)
        return Hierarchy(empty, empty.copy(), none, none.copy(), none.copy())

    def add(begin: int, end: int) -> int:
        members = order[begin:end]
        nodes_low.append(low[members].min(axis=0))
        nodes_high.append(high[members].max(axis=0))
        first.append(begin)
        count.append(end - begin)
        return len(first) - 1

    pending = [(add(0, len(low)), 0, len(low))]
    while pending:
        node, begin, end = pending.pop()
        if end - begin <= LEAF_SIZE:
            continue
        members = order[begin:end]
        spread = np.ptp(centres[members], axis=0)
        axis = int(np.argmax(spread))
        order[begin:end] = members[np.argsort(centres[members, axis], kind="stable")]
        middle = (begin + end) // 2
        left = add(begin, middle)
        add(middle, end)
        first[node], count[node] = left, 0
        pending += [(left, begin, middle), (left + 1, middle, end)]
    return Hierarchy(
        np.array(nodes_low),
        np.array(nodes_high),
        np.array(first, dtype=np.int64),
        np.array(count, dtype=np.int64),
        order.astype(np.int64),
    )


def stack() -> NDArray[np.int64]:
    """Scratch for one traversal (kept in a checker's workspace: nothing is allocated per
    configuration)."""
    return np.zeros(STACK_SIZE, dtype=np.int64)
