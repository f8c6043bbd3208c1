"""The collision checker's broad phase: the oriented boxes of bodies, their world-aligned
bounds, and the tests that keep only the (configuration, body, obstacle) triples fcl must
decide (:mod:`flycrane.world.collision`). Vectorized over configurations."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from flycrane.world.bodies import Body


@dataclass(frozen=True)
class BoxSet:
    """Oriented boxes of several bodies in their parent frame, stacked for vectorized use."""

    centers: NDArray[np.float64]  #: (B, 3)
    axes: NDArray[np.float64]  #: (B, 3, 3)
    halves: NDArray[np.float64]  #: (B, 3)

    @classmethod
    def of(cls, bodies: list[Body]) -> BoxSet:
        if not bodies:
            return cls(np.zeros((0, 3)), np.zeros((0, 3, 3)), np.zeros((0, 3)))
        return cls(
            np.stack([b.box_center for b in bodies]),
            np.stack([b.rotation for b in bodies]),
            np.stack([b.half_size for b in bodies]),
        )


def world_boxes(
    boxes: BoxSet, position: NDArray[np.float64], rotation: NDArray[np.float64]
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """World-aligned boxes (centres, half sizes) of platform-fixed bodies, each (N, B, 3).

    A box with axes ``R`` and half sizes ``h`` spans ``|R| h`` along the world axes.
    """
    centers, axes, halves = boxes.centers, boxes.axes, boxes.halves
    world_centers = position[:, None, :] + np.einsum("nab,kb->nka", rotation, centers)
    world_axes = np.einsum("nab,kbc->nkac", rotation, axes)
    return world_centers, np.einsum("nkac,kc->nka", np.abs(world_axes), halves)


def static_boxes(boxes: BoxSet) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """World-aligned boxes (centres, half sizes) of world-fixed bodies, each (B, 3)."""
    return boxes.centers, np.einsum("kac,kc->ka", np.abs(boxes.axes), boxes.halves)


def sphere_touches_boxes(
    centers: NDArray[np.float64], radius: float, boxes: BoxSet
) -> NDArray[np.bool_]:
    """Whether spheres (..., 3) touch oriented boxes (O,), exactly: (..., O).

    The sphere centre, in each box's frame, is clamped to the box; the sphere touches it
    when that closest point is within the radius.
    """
    local = np.einsum("oba,...ob->...oa", boxes.axes, centers[..., None, :] - boxes.centers)
    outside = local - np.clip(local, -boxes.halves, boxes.halves)
    return np.einsum("...a,...a->...", outside, outside) <= radius**2


def segment_near_boxes(
    start: NDArray[np.float64], end: NDArray[np.float64], margin: float, boxes: BoxSet
) -> NDArray[np.bool_]:
    """Whether segments (..., 3) cross oriented boxes grown by ``margin`` on every side.

    Slab test in each box's frame. A capsule of radius ``margin`` can only touch a box if
    its axis crosses the box grown by the margin, so False is exact and True needs a narrow
    check (near the grown box's edges and corners the capsule may still miss).
    """
    p0 = np.einsum("oba,...ob->...oa", boxes.axes, start[..., None, :] - boxes.centers)
    p1 = np.einsum("oba,...ob->...oa", boxes.axes, end[..., None, :] - boxes.centers)
    d = p1 - p0
    half = boxes.halves + margin
    flat = np.abs(d) < 1e-12
    safe = np.where(flat, 1.0, d)
    t1, t2 = (-half - p0) / safe, (half - p0) / safe
    low = np.where(flat, np.where(np.abs(p0) <= half, -np.inf, np.inf), np.minimum(t1, t2))
    high = np.where(flat, np.where(np.abs(p0) <= half, np.inf, -np.inf), np.maximum(t1, t2))
    return np.maximum(low.max(axis=-1), 0.0) <= np.minimum(high.min(axis=-1), 1.0)


def near_platform_boxes(
    boxes: BoxSet,
    position: NDArray[np.float64],
    rotation: NDArray[np.float64],
    drones: tuple[NDArray[np.float64], float],
    cables: tuple[NDArray[np.float64], NDArray[np.float64], float],
) -> tuple[NDArray[np.bool_], NDArray[np.bool_]]:
    """Which drones (N, 3, B) and cables (N, 6, B) may touch boxes fixed to the platform
    at poses (``position`` (N, 3), ``rotation`` (N, 3, 3)). ``drones``: world centres
    (N, 3, 3) and radius; ``cables``: world ends (N, 6, 3) twice and radius. Tested in the
    platform frame, where the boxes stand still: exact for drones, a slab test for cables."""

    def local(x: NDArray[np.float64]) -> NDArray[np.float64]:
        return np.einsum("nba,nkb->nka", rotation, x - position[:, None, :])

    (centers, radius), (start, end, margin) = drones, cables
    near_drones = sphere_touches_boxes(local(centers), radius, boxes)
    return near_drones, segment_near_boxes(local(start), local(end), margin, boxes)
