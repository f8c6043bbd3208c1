"""Compiled collision checks of configurations: the planner's fast path (design.md s.6).

The same bodies and rules as :class:`flycrane.world.collision.CollisionChecker` (python-fcl), which
stays the reference this kernel is tested against and the checker of payload meshes:

- robot: drones (spheres at A_k), cables (capsules b_i -> A_i), the platform (the prism
  through the B'_i, a convex polytope) and the payload's boxes, cylinders and spheres;
- against the obstacles (boxes, cylinders and spheres grown by the scene's clearance, the
  faces of triangle meshes kept within it: a margin, so that a mesh keeps the clearance
  exactly as a primitive does) and the ground (raised by it);
- self: drone centres at least ``min_drone_separation`` apart, no drone touching another
  drone's cables, no drone or cable touching the payload (cables without their first
  ``cable_clearance_at_platform`` metres).

Per configuration, one compiled pass in three parts: the pose (platform and payload, which
no alpha moves), each drone with its two cables (what its alpha moves), and the formation
(drone separations, drones against other drones' cables); the planner uses the parts
alone to choose the alphas of a pose. Every body's box descends the obstacles' hierarchy
(:mod:`flycrane.world.bvh`) and the overlapping pairs are decided by
:mod:`flycrane.world.primitives` (exact closed forms for spheres, GJK with proven bounds
otherwise). Nothing is allocated per
configuration; a batch shares one :func:`workspace`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from flycrane.kernels import kernel
from flycrane.model.cable_system import CableSystem
from flycrane.model.pose_kernel import drone_offset, rotation_into
from flycrane.model.system_spec import DRONE_CABLES
from flycrane.world.bodies import platform_prism
from flycrane.world.bvh import build_hierarchy, stack
from flycrane.world.primitives import (
    BOX,
    CYLINDER,
    GJK_WORK,
    POINT,
    POLYTOPE,
    SEGMENT,
    TRIANGLE,
    bounds,
    point_distance_squared,
    shapes_touch,
)
from flycrane.world.scene import Box, Cylinder, Mesh, SceneSpec, Sphere

#: Robot-body rows, drone by drone: drone k at 3k, its cables DRONE_CABLES[k] at 3k + 1 and
#: 3k + 2 (so each drone's bodies are one range), the platform at 9, the payload from 10.
_FIXED_BODIES = 10
_PLATFORM = 9
#: Platform point b_i where each cable row starts (rows 3k + 1 + m: cable DRONE_CABLES[k][m]).
_CABLE_POINTS = np.array(DRONE_CABLES, dtype=np.int64)


def _primitives(
    shapes, base_dir: Path | None = None, mesh_margin: float | None = None
) -> tuple[np.ndarray, ...]:
    """(kind, centre, rotation, size, margin) arrays of boxes, cylinders and spheres, and
    with ``mesh_margin`` the faces of meshes (a face's corners are its rotation's rows),
    each with that margin; without it meshes are left out."""
    kind: list[np.ndarray] = []
    center: list[np.ndarray] = []
    rot: list[np.ndarray] = []
    size: list[np.ndarray] = []
    margin: list[np.ndarray] = []
    for shape in shapes:
        if isinstance(shape, Mesh):
            if mesh_margin is None:
                continue
            vertices, faces = shape.triangles(base_dir)
            pose = shape.axes
            world = np.asarray(vertices, float) @ pose.T + np.array(shape.center, dtype=float)
            corners = world[np.asarray(faces, dtype=np.int64).reshape(-1, 3)]
            normals = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
            corners = corners[np.linalg.norm(normals, axis=1) > 0.0]  # no area: no face
            count = len(corners)
            kind.append(np.full(count, TRIANGLE, dtype=np.int64))
            center.append(corners.mean(axis=1))
            rot.append(corners)
            size.append(np.zeros((count, 3)))
            margin.append(np.full(count, mesh_margin, dtype=float))
            continue
        center.append(np.array(shape.center, dtype=float).reshape(1, 3))
        rot.append(shape.axes.reshape(1, 3, 3))
        if isinstance(shape, Box):
            kind.append(np.array([BOX], dtype=np.int64))
            size.append((np.array(shape.size) / 2).reshape(1, 3))
            margin.append(np.zeros(1))
        elif isinstance(shape, Cylinder):
            kind.append(np.array([CYLINDER], dtype=np.int64))
            size.append(np.array([[shape.radius, shape.height / 2, 0.0]]))
            margin.append(np.zeros(1))
        elif isinstance(shape, Sphere):
            kind.append(np.array([POINT], dtype=np.int64))
            size.append(np.zeros((1, 3)))
            margin.append(np.array([shape.radius], dtype=float))
    return (
        np.concatenate([np.zeros(0, dtype=np.int64), *kind]),
        np.concatenate([np.zeros((0, 3)), *center]).astype(float, copy=False),
        np.concatenate([np.zeros((0, 3, 3)), *rot]).astype(float, copy=False),
        np.concatenate([np.zeros((0, 3)), *size]).astype(float, copy=False),
        np.concatenate([np.zeros(0), *margin]).astype(float, copy=False),
    )


#: Triangles whose bounds :func:`_world_boxes` computes at once (bounding its scratch).
_BOUNDS_CHUNK = 1 << 18


def _world_boxes(kind, center, rot, size, margin) -> tuple[np.ndarray, np.ndarray]:
    """Axis-aligned bounds (low, high) of world-fixed primitives, each (O, 3)."""
    half = np.zeros_like(center)
    for o in np.flatnonzero((kind == BOX) | (kind == CYLINDER)):
        if kind[o] == BOX:
            half[o] = np.abs(rot[o]) @ size[o]
        else:
            axis = rot[o][:, 2]
            half[o] = size[o, 0] * np.sqrt(np.clip(1 - axis**2, 0, 1)) + size[o, 1] * np.abs(axis)
    triangles = np.flatnonzero(kind == TRIANGLE)
    for first in range(0, len(triangles), _BOUNDS_CHUNK):
        chosen = triangles[first : first + _BOUNDS_CHUNK]
        corners, middle = rot[chosen], center[chosen]
        half[chosen] = np.maximum(corners.max(axis=1) - middle, middle - corners.min(axis=1))
    half += margin[:, None]
    return center - half, center + half


@dataclass(frozen=True, eq=False)
class CompiledScene:
    """A scene's obstacles, payload and collision settings as the kernel's arrays.

    ``payload_meshes``: the payload has triangle meshes, which only fcl checks;
    configurations the kernel finds free must then also pass the fcl checker.
    """

    arrays: tuple
    payload_meshes: bool

    @classmethod
    def build(
        cls, system: CableSystem, scene: SceneSpec, base_dir: Path | None = None
    ) -> CompiledScene:
        settings = scene.collision
        obstacles = _primitives(scene.grown_obstacles(), base_dir, settings.obstacle_clearance)
        low, high = _world_boxes(*obstacles)
        payload = _primitives(scene.payload.shapes)
        vertices, _ = platform_prism(system, settings.platform_thickness)
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
        # Robot bodies (rows: _FIXED_BODIES): per drone a point and two segments, the
        # platform, the payload.
        body_kind = np.array([POINT, SEGMENT, SEGMENT] * 3 + [POLYTOPE], dtype=np.int64)
        body_margin = np.array(
            [settings.drone_radius, settings.cable_radius, settings.cable_radius] * 3 + [0.0]
        )
        arrays = (
            *obstacles,
            low,
            high,
            *payload,
            np.ascontiguousarray(vertices),
            params,
            _CABLE_POINTS,
            np.concatenate([body_kind, payload[0]]),
            np.concatenate([body_margin, payload[4]]),
            *build_hierarchy(low, high).arrays(),
        )
        return cls(arrays, any(isinstance(s, Mesh) for s in scene.payload.shapes))

    def workspace(self) -> tuple:
        """Scratch tables for :func:`collision_free_row`, one per batch: the robot bodies'
        world centres (cable starts), sizes (cable ends), rotations and bounds, the
        platform's world vertices, GJK scratch, the hierarchy's traversal stack; the
        bodies' last row is a spare shape."""
        bodies = len(self.arrays[15])
        vertices = len(self.arrays[12])
        return (
            np.zeros((bodies + 1, 3)),
            np.zeros((bodies + 1, 3)),
            np.zeros((bodies + 1, 3, 3)),
            np.zeros((vertices, 3)),
            np.zeros((bodies, 2, 3)),
            np.zeros((GJK_WORK, 3)),
            stack(),
        )


@kernel(inline="always")
def _bodies_free(first, last, scene, work) -> bool:
    """Robot bodies first..last-1 (placed) against the ground and the obstacles; fills
    their bounds.

    Shape kinds are always passed from the kinds array, never as constants: numba types a
    constant argument as a literal, and every literal compiles the callees again.
    """
    obs_kind, obs_center, obs_rot, obs_size, obs_margin, obs_low, obs_high = scene[:7]
    params, kinds, margins = scene[13], scene[15], scene[16]
    node_low, node_high, node_first, node_count, order = scene[17:22]
    centers, sizes, rots, verts, boxes, gjk, pending = work
    for b in range(first, last):
        bounds(kinds[b], b, centers, rots, sizes, verts, margins[b], boxes, b)
        if params[5] > 0.0 and boxes[b, 0, 2] <= params[4]:
            return False
        top = 0
        if node_count.shape[0] > 0:
            pending[0], top = 0, 1
        while top > 0:  # down the hierarchy, through the nodes the body's box overlaps
            top -= 1
            m = pending[top]
            if not _box_overlaps(boxes, b, node_low, node_high, m):
                continue
            if node_count[m] == 0:
                pending[top], pending[top + 1] = node_first[m], node_first[m] + 1
                top += 2
                continue
            for i in range(node_first[m], node_first[m] + node_count[m]):
                o = order[i]
                if _box_overlaps(boxes, b, obs_low, obs_high, o) and shapes_touch(
                    kinds[b], b, centers, rots, sizes, verts,
                    obs_kind[o], o, obs_center, obs_rot, obs_size, verts,
                    margins[b] + obs_margin[o], gjk,
                ):  # fmt: skip
                    return False
    return True


@kernel(inline="always")
def _box_overlaps(boxes, b, low, high, o) -> bool:
    """Body b's box (boxes[b]: low, high) against box o of ``low``, ``high`` (O, 3)."""
    for axis in range(3):
        if boxes[b, 0, axis] > high[o, axis] or boxes[b, 1, axis] < low[o, axis]:
            return False
    return True


@kernel(inline="always")
def pose_free(q, kin, scene, work) -> bool:
    """Place the platform pose of q (R, cable starts b_i, platform, payload) and check the
    platform and the payload, which no alpha moves. The first part of
    :func:`collision_free_row`; :func:`drone_free` and :func:`formation_free` follow it."""
    rotation_into(q, work[2][scene[15].shape[0]])  # R (paper eq. 1) lives in the spare row
    return pose_placed_free(q, kin, scene, work)


@kernel(inline="always")
def pose_placed_free(q, kin, scene, work) -> bool:
    """:func:`pose_free` with q's rotation R in the rotations' spare row already."""
    points = kin[0]
    pay_center, pay_rot, pay_size, plat_local = scene[8], scene[9], scene[10], scene[12]
    cable_points = scene[14]
    centers, sizes, rots, verts = work[0], work[1], work[2], work[3]
    spare = scene[15].shape[0]
    rot = rots[spare]
    for k in range(3):
        for m in range(2):
            i = cable_points[k, m]
            for a in range(3):
                acc = q[a]
                for c in range(3):
                    acc += rot[a, c] * points[i, c]
                centers[3 * k + 1 + m, a] = acc
    for v in range(plat_local.shape[0]):
        for a in range(3):
            acc = q[a]
            for c in range(3):
                acc += rot[a, c] * plat_local[v, c]
            verts[v, a] = acc
    for b in range(_FIXED_BODIES, spare):
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
    return _bodies_free(_PLATFORM, spare, scene, work)


@kernel(inline="always")
def drone_free(q, k, kin, scene, work) -> bool:
    """Place drone k at its alpha q[6 + k] with its two cables (after :func:`pose_free`)
    and check them against the ground, the obstacles and the payload (cables without their
    first ``cable_clearance_at_platform`` metres): everything drone k's alpha moves but
    the other drones."""
    _, foot, radius, outward, up = kin
    return drone_placed_free(q, k, drone_offset(q, k, foot, radius, outward, up), scene, work)


@kernel(inline="always")
def drone_placed_free(q, k, offset, scene, work) -> bool:
    """:func:`drone_free` with drone k's position in the platform frame given, ``offset``
    (3,) (:func:`~flycrane.model.pose_kernel.drone_offset`)."""
    params, kinds, margins = scene[13], scene[15], scene[16]
    centers, sizes, rots, verts, boxes, gjk = work[:6]
    spare = kinds.shape[0]
    rot = rots[spare]
    drone = 3 * k
    for a in range(3):
        acc = q[a]
        for c in range(3):
            acc += rot[a, c] * offset[c]
        centers[drone, a] = acc
        sizes[drone + 1, a] = sizes[drone + 2, a] = acc
    if not _bodies_free(drone, drone + 3, scene, work):
        return False
    for p in range(_FIXED_BODIES, spare):
        if _box_overlaps(boxes, drone, boxes[:, 0], boxes[:, 1], p) and shapes_touch(
            kinds[drone], drone, centers, rots, sizes, verts,
            kinds[p], p, centers, rots, sizes, verts,
            params[0] + margins[p], gjk,
        ):  # fmt: skip
            return False
        for cable in range(drone + 1, drone + 3):
            if not _box_overlaps(boxes, cable, boxes[:, 0], boxes[:, 1], p):
                continue
            length = 0.0
            for a in range(3):
                length += (sizes[cable, a] - centers[cable, a]) ** 2
            fraction = min(1.0, params[3] / math.sqrt(length)) if length > 0.0 else 1.0
            for a in range(3):
                centers[spare, a] = centers[cable, a] + fraction * (
                    sizes[cable, a] - centers[cable, a]
                )
                sizes[spare, a] = sizes[cable, a]
            if shapes_touch(
                kinds[cable], spare, centers, rots, sizes, verts,
                kinds[p], p, centers, rots, sizes, verts,
                params[1] + margins[p], gjk,
            ):  # fmt: skip
                return False
    return True


@kernel(inline="always")
def formation_free(scene, work) -> bool:
    """Drone centres at least the separation apart, no drone touching another drone's
    cables (after :func:`drone_free` placed all three)."""
    params, kinds = scene[13], scene[15]
    centers, sizes, rots = work[0], work[1], work[2]
    reach = (params[0] + params[1]) ** 2
    for k in range(3):
        for m in range(3):
            if m == k:
                continue
            if m > k:
                gap = 0.0
                for a in range(3):
                    gap += (centers[3 * k, a] - centers[3 * m, a]) ** 2
                if gap < params[2] * params[2]:
                    return False
            for cable in range(3 * m + 1, 3 * m + 3):
                d = point_distance_squared(
                    centers[3 * k], kinds[cable], cable, centers, rots, sizes
                )
                if d < reach:
                    return False
    return True


@kernel(inline="always")
def collision_free_row(q, kin, scene, work) -> bool:
    """Whether configuration q (9,) collides with nothing (module docstring).

    ``kin``: :func:`kinematic_arrays`; ``scene``: :attr:`CompiledScene.arrays`; ``work``:
    :meth:`CompiledScene.workspace`.
    """
    if not pose_free(q, kin, scene, work):
        return False
    # A loop, not drone_free(q, 0, ...) ... (q, 2, ...): constant arguments are literals to
    # numba, which would compile drone_free three times.
    for k in range(3):
        if not drone_free(q, k, kin, scene, work):
            return False
    return formation_free(scene, work)


@kernel(inline="always")
def collision_free_posed(q, rot, offsets, kin, scene, work) -> bool:
    """:func:`collision_free_row` of q whose pose a state check computed already
    (:mod:`flycrane.model.pose_kernel`): its rotation R (3, 3) and its drones' positions in
    the platform frame ``offsets`` (3, 3)."""
    spare = work[2][scene[15].shape[0]]
    for a in range(3):
        for c in range(3):
            spare[a, c] = rot[a, c]
    if not pose_placed_free(q, kin, scene, work):
        return False
    for k in range(3):
        if not drone_placed_free(q, k, offsets[k], scene, work):
            return False
    return formation_free(scene, work)


@kernel()
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
    """Kernel verdicts for configurations (N, 9), ignoring payload meshes (N,)."""
    q = np.ascontiguousarray(q, dtype=float).reshape(-1, 9)
    out = np.empty(len(q), dtype=np.bool_)
    _collision_free_rows(q, kinematic_arrays(system), compiled.arrays, compiled.workspace(), out)
    return out
