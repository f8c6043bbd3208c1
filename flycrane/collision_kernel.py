"""Compiled collision checks of configurations: the planner's fast path (design.md s.6).

The same bodies and rules as :class:`flycrane.collision.CollisionChecker` (python-fcl), which
stays the reference this kernel is tested against and the checker of triangle meshes:

- robot: drones (spheres at A_k), cables (capsules b_i -> A_i), the platform (the prism
  through the B'_i, a convex polytope) and the payload's boxes, cylinders and spheres;
- against the obstacles (grown by the scene's clearance) and the ground (raised by it);
- self: drone centres at least ``min_drone_separation`` apart, no drone touching another
  drone's cables, no drone or cable touching the payload (cables without their first
  ``cable_clearance_at_platform`` metres).

Per configuration, one compiled pass: pose every body, box-test it against each obstacle,
and decide the overlapping pairs with :mod:`flycrane.collision_primitives` (exact closed
forms for spheres, GJK with proven bounds otherwise). Nothing is allocated per
configuration; a batch shares one :func:`workspace`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numba
import numpy as np

from flycrane.cable_system import CABLE_DRONE, CableSystem
from flycrane.collision_geometry import platform_body
from flycrane.collision_primitives import (
    BOX,
    CYLINDER,
    GJK_WORK,
    POINT,
    POLYTOPE,
    SEGMENT,
    bounds,
    point_distance_squared,
    shapes_touch,
)
from flycrane.kinematics import matrix_from_tilt_torsion
from flycrane.scene import Box, Cylinder, Mesh, SceneSpec, Sphere

_CABLE_DRONE = np.array(CABLE_DRONE, dtype=np.int64)
#: Rows of the robot-body tables before the payload's: 3 drones, 6 cables, the platform.
_FIXED_BODIES = 10


def _primitives(shapes) -> tuple[np.ndarray, ...]:
    """(kind, centre, rotation, size, margin) arrays of boxes, cylinders and spheres."""
    kind, center, rot, size, margin = [], [], [], [], []
    for shape in shapes:
        if isinstance(shape, Mesh):
            continue
        center.append(np.array(shape.center, dtype=float))
        rot.append(matrix_from_tilt_torsion(np.array(shape.rotation, dtype=float)))
        if isinstance(shape, Box):
            kind.append(BOX)
            size.append(np.array(shape.size) / 2)
            margin.append(0.0)
        elif isinstance(shape, Cylinder):
            kind.append(CYLINDER)
            size.append(np.array([shape.radius, shape.height / 2, 0.0]))
            margin.append(0.0)
        elif isinstance(shape, Sphere):
            kind.append(POINT)
            size.append(np.zeros(3))
            margin.append(shape.radius)
    n = len(kind)
    return (
        np.array(kind, dtype=np.int64),
        np.array(center, dtype=float).reshape(n, 3),
        np.array(rot, dtype=float).reshape(n, 3, 3),
        np.array(size, dtype=float).reshape(n, 3),
        np.array(margin, dtype=float),
    )


def _world_boxes(kind, center, rot, size, margin) -> tuple[np.ndarray, np.ndarray]:
    """Axis-aligned bounds (low, high) of world-fixed primitives, each (O, 3)."""
    half = np.zeros_like(center)
    for o in range(len(kind)):
        if kind[o] == BOX:
            half[o] = np.abs(rot[o]) @ size[o]
        elif kind[o] == CYLINDER:
            axis = rot[o][:, 2]
            half[o] = size[o, 0] * np.sqrt(np.clip(1 - axis**2, 0, 1)) + size[o, 1] * np.abs(axis)
        half[o] += margin[o]
    return center - half, center + half


@dataclass(frozen=True, eq=False)
class CompiledScene:
    """A scene's obstacles, payload and collision settings as the kernel's arrays.

    ``has_meshes``: the scene has triangle meshes, which only fcl checks; configurations
    the kernel finds free must then also pass the fcl checker.
    """

    arrays: tuple
    has_meshes: bool

    @classmethod
    def build(cls, system: CableSystem, scene: SceneSpec) -> CompiledScene:
        settings = scene.collision
        obstacles = _primitives(scene.grown_obstacles())
        low, high = _world_boxes(*obstacles)
        payload = _primitives(scene.payload.shapes)
        prism = platform_body(system, settings.platform_thickness)
        ring = np.unique(np.round(system.platform_points, 12), axis=0)
        half = np.array([0.0, 0.0, settings.platform_thickness / 2])
        vertices = np.concatenate([ring + half, ring - half])
        assert np.allclose(prism.box_center + prism.half_size, vertices.max(axis=0))
        params = np.array(
            [
                settings.drone_radius,
                settings.cable_radius,
                settings.min_drone_separation,
                settings.cable_clearance_at_platform,
                settings.obstacle_clearance,  # the raised ground
                float(scene.ground),
            ]
        )
        # Robot bodies: 3 drones (points), 6 cables (segments), the platform, the payload.
        body_kind = np.array([POINT] * 3 + [SEGMENT] * 6 + [POLYTOPE], dtype=np.int64)
        body_margin = np.array([settings.drone_radius] * 3 + [settings.cable_radius] * 6 + [0.0])
        arrays = (
            *obstacles,
            low,
            high,
            *payload,
            np.ascontiguousarray(vertices),
            params,
            _CABLE_DRONE,
            np.concatenate([body_kind, payload[0]]),
            np.concatenate([body_margin, payload[4]]),
        )
        meshes = any(isinstance(s, Mesh) for s in (*scene.obstacles, *scene.payload.shapes))
        return cls(arrays, meshes)

    def workspace(self) -> tuple:
        """Scratch tables for :func:`collision_free_row`, one per batch: the robot bodies'
        world centres (cable starts), sizes (cable ends), rotations and bounds, the
        platform's world vertices, GJK scratch; the bodies' last row is a spare shape."""
        bodies = len(self.arrays[-2])
        vertices = len(self.arrays[12])
        return (
            np.zeros((bodies + 1, 3)),
            np.zeros((bodies + 1, 3)),
            np.zeros((bodies + 1, 3, 3)),
            np.zeros((vertices, 3)),
            np.zeros((bodies, 2, 3)),
            np.zeros((GJK_WORK, 3)),
        )


@numba.njit(cache=True, nogil=True)
def collision_free_row(q, kin, scene, work) -> bool:
    """Whether configuration q (9,) collides with nothing (module docstring).

    ``kin``: :func:`kinematic_arrays`; ``scene``: :attr:`CompiledScene.arrays`; ``work``:
    :meth:`CompiledScene.workspace`.
    """
    points, foot, radius, outward, up = kin
    (
        obs_kind,
        obs_center,
        obs_rot,
        obs_size,
        obs_margin,
        obs_low,
        obs_high,
        _pay_kind,
        pay_center,
        pay_rot,
        pay_size,
        _pay_margin,
        plat_local,
        params,
        cable_drone,
        kinds,
        margins,
    ) = scene
    centers, sizes, rots, verts, boxes, gjk = work
    drone_r, cable_r, separation, skip, ground_z = (
        params[0],
        params[1],
        params[2],
        params[3],
        params[4],
    )
    ground = params[5] > 0.0
    spare = kinds.shape[0]
    # Pose (paper eq. 1-2): R into the spare rotation, drones A_k, cables b_i -> A_k,
    # platform vertices, payload shapes.
    rot = rots[spare]
    phi, theta, sigma = q[3], q[4], q[5]
    cp, sp, ct, st = math.cos(phi), math.sin(phi), math.cos(theta), math.sin(theta)
    cs, ss = math.cos(sigma - phi), math.sin(sigma - phi)
    rot[0, 0], rot[0, 1], rot[0, 2] = cp * ct * cs - sp * ss, -cp * ct * ss - sp * cs, cp * st
    rot[1, 0], rot[1, 1], rot[1, 2] = sp * ct * cs + cp * ss, -sp * ct * ss + cp * cs, sp * st
    rot[2, 0], rot[2, 1], rot[2, 2] = -st * cs, st * ss, ct
    for k in range(3):
        ca, sa = math.cos(q[6 + k]), math.sin(q[6 + k])
        for a in range(3):
            acc = q[a]
            for c in range(3):
                acc += rot[a, c] * (foot[k, c] + radius[k] * (ca * outward[k, c] + sa * up[k, c]))
            centers[k, a] = acc
    for i in range(6):
        for a in range(3):
            acc = q[a]
            for c in range(3):
                acc += rot[a, c] * points[i, c]
            centers[3 + i, a] = acc
            sizes[3 + i, a] = centers[cable_drone[i], a]
    for v in range(plat_local.shape[0]):
        for a in range(3):
            acc = q[a]
            for c in range(3):
                acc += rot[a, c] * plat_local[v, c]
            verts[v, a] = acc
    n_bodies = spare
    for b in range(_FIXED_BODIES, n_bodies):
        j = b - _FIXED_BODIES
        for a in range(3):
            acc = q[a]
            for c in range(3):
                acc += rot[a, c] * pay_center[j, c]
                total = 0.0
                for m in range(3):
                    total += rot[a, m] * pay_rot[j, m, c]
                rots[b, a, c] = total
            centers[b, a] = acc
            sizes[b, a] = pay_size[j, a]
    # Self: drone separation, drones against other drones' cables.
    reach = (drone_r + cable_r) ** 2
    for k in range(3):
        for m in range(k + 1, 3):
            gap = 0.0
            for a in range(3):
                gap += (centers[k, a] - centers[m, a]) ** 2
            if gap < separation * separation:
                return False
        for i in range(6):
            if cable_drone[i] != k:
                if point_distance_squared(centers[k], SEGMENT, 3 + i, centers, rots, sizes) < reach:
                    return False
    # Bounds of every body (margins added); the ground.
    for b in range(n_bodies):
        bounds(kinds[b], b, centers, rots, sizes, verts, margins[b], boxes, b)
        if ground and boxes[b, 0, 2] <= ground_z:
            return False
    # Drones and cables (without their first ``skip`` metres) against the payload.
    for p in range(_FIXED_BODIES, n_bodies):
        for k in range(3):
            if _boxes_overlap(boxes, k, boxes, p) and shapes_touch(
                POINT, k, centers, rots, sizes, verts,
                kinds[p], p, centers, rots, sizes, verts,
                drone_r + margins[p], gjk,
            ):  # fmt: skip
                return False
        for i in range(3, 9):
            if not _boxes_overlap(boxes, i, boxes, p):
                continue
            length = 0.0
            for a in range(3):
                length += (sizes[i, a] - centers[i, a]) ** 2
            fraction = min(1.0, skip / math.sqrt(length)) if length > 0.0 else 1.0
            for a in range(3):
                centers[spare, a] = centers[i, a] + fraction * (sizes[i, a] - centers[i, a])
                sizes[spare, a] = sizes[i, a]
            if shapes_touch(
                SEGMENT, spare, centers, rots, sizes, verts,
                kinds[p], p, centers, rots, sizes, verts,
                cable_r + margins[p], gjk,
            ):  # fmt: skip
                return False
    # Every body against every obstacle whose bounds its own bounds overlap.
    for b in range(n_bodies):
        for o in range(obs_kind.shape[0]):
            if (
                boxes[b, 0, 0] > obs_high[o, 0]
                or boxes[b, 1, 0] < obs_low[o, 0]
                or boxes[b, 0, 1] > obs_high[o, 1]
                or boxes[b, 1, 1] < obs_low[o, 1]
                or boxes[b, 0, 2] > obs_high[o, 2]
                or boxes[b, 1, 2] < obs_low[o, 2]
            ):
                continue
            if shapes_touch(
                kinds[b], b, centers, rots, sizes, verts,
                obs_kind[o], o, obs_center, obs_rot, obs_size, verts,
                margins[b] + obs_margin[o], gjk,
            ):  # fmt: skip
                return False
    return True


@numba.njit(cache=True, nogil=True)
def _boxes_overlap(boxes_a, a, boxes_b, b) -> bool:
    for axis in range(3):
        if boxes_a[a, 0, axis] > boxes_b[b, 1, axis] or boxes_a[a, 1, axis] < boxes_b[b, 0, axis]:
            return False
    return True


@numba.njit(cache=True, nogil=True)
def _collision_free_rows(q, kin, scene, work, out) -> None:
    for row in range(q.shape[0]):
        out[row] = collision_free_row(q[row], kin, scene, work)


def kinematic_arrays(system: CableSystem) -> tuple:
    """The system's arrays :func:`collision_free_row` poses bodies with."""
    return (
        np.ascontiguousarray(system.platform_points),
        np.ascontiguousarray(system.drone_foot),
        np.ascontiguousarray(system.drone_radius),
        np.ascontiguousarray(system.drone_outward),
        np.ascontiguousarray(system.drone_up),
    )


def collision_free(system: CableSystem, compiled: CompiledScene, q: np.ndarray) -> np.ndarray:
    """Kernel verdicts for configurations (N, 9), ignoring meshes (N,)."""
    q = np.ascontiguousarray(q, dtype=float).reshape(-1, 9)
    out = np.empty(len(q), dtype=np.bool_)
    _collision_free_rows(q, kinematic_arrays(system), compiled.arrays, compiled.workspace(), out)
    return out
