"""Collision bodies of a scene as fcl objects plus oriented boxes for the broad phase.

Every shape (obstacle, payload part, the platform) becomes a :class:`Body`: the fcl
geometry that decides contacts exactly, and an oriented bounding box (centre, rotation,
half sizes, in its parent frame) from which :mod:`flycrane.world.collision`'s broad phase
gets world-aligned boxes for many configurations at once.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import NoReturn

import fcl
import numpy as np
from numpy.typing import NDArray

from flycrane.errors import FieldProblem, InputError
from flycrane.model.cable_system import CableSystem
from flycrane.quantities import MAX_LENGTH
from flycrane.world.memo import SharedCache, array_digest, read_only
from flycrane.world.scene import Box, Cylinder, Mesh, SceneSpec, Sphere

#: Largest extent of a usable body [m]: a shape within MAX_LENGTH of its frame's origin,
#: posed within MAX_LENGTH of the world's. Beyond it the broad phase's squared distances lose
#: the precision that decides a contact, and at overflow a body is never checked at all.
USABLE_EXTENT = 4.0 * MAX_LENGTH


class CollisionBodyError(InputError):
    """A shape the collision checker cannot use (not finite, too large, no triangle).

    Raised instead of building a checker that would silently never see the body.
    """


@dataclass(frozen=True, eq=False)
class Body:
    """One rigid collision shape: fcl object and its oriented box in the parent frame."""

    name: str
    geometry: fcl.CollisionGeometry
    center: NDArray[np.float64]  #: (3,) shape origin in the parent frame
    rotation: NDArray[np.float64]  #: (3, 3) shape axes in the parent frame
    box_center: NDArray[np.float64]  #: (3,) bounding-box centre, parent frame
    half_size: NDArray[np.float64]  #: (3,) bounding-box half sizes along ``rotation``'s axes
    obstacle: fcl.CollisionObject | None = None  #: placed once, for static bodies
    #: how far from the body every robot body must stay [m]: the clearance of a mesh, which
    #: cannot be grown (0 for grown primitives); the box above includes it
    margin: float = 0.0


def box_corners(body: Body) -> NDArray[np.float64]:
    """The eight corners (8, 3) of a body's bounding box, in its parent frame."""
    signs = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], dtype=float)
    return body.box_center + (signs * body.half_size) @ body.rotation.T


def _bvh(vertices: NDArray, faces: NDArray) -> fcl.BVHModel:
    model = fcl.BVHModel()
    model.beginModel(len(vertices), len(faces))
    model.addSubModel(vertices, faces)
    model.endModel()
    return model


#: fcl hierarchies of meshes kept per process, shared by every checker of their scene
#: (:func:`_mesh_model`): of at most this many faces in all (fcl's hierarchy takes some
#: 500 bytes a face).
MESH_MODEL_CACHE_FACES = 3_000_000

_mesh_models: SharedCache[tuple[fcl.BVHModel, NDArray, NDArray, int]] = SharedCache(
    MESH_MODEL_CACHE_FACES, lambda model: model[3]
)


def _mesh_model(
    vertices: NDArray, faces: NDArray, field: str, name: str
) -> tuple[fcl.BVHModel, NDArray, NDArray]:
    """A mesh's fcl hierarchy and its vertices' bounds (low, high) (3,) each, once
    :func:`require_triangles` has accepted it; built once per process for equal vertices
    and faces, whatever scene and clearance they come with (they are the mesh's own, in its
    frame): fcl only reads a hierarchy it checks against, so checkers share it.

    Raises
    ------
    CollisionBodyError
        As :func:`require_triangles`.
    """
    key = array_digest(np.asarray(vertices, dtype=float), np.asarray(faces, dtype=int))
    cached = _mesh_models.get(key)
    if cached is None:
        require_triangles(vertices, faces, field, name)
        low, high = vertices.min(axis=0), vertices.max(axis=0)
        cached = (_bvh(vertices, faces), read_only(low), read_only(high), len(faces))
        _mesh_models.put(key, cached)
    return cached[:3]


def body_from_shape(
    shape: Box | Cylinder | Sphere | Mesh, name: str, base_dir: Path | None, field: str = ""
) -> Body:
    """A :class:`Body` for a scene shape (pose relative to its parent frame).

    Raises
    ------
    CollisionBodyError
        If the checker could not use the body (:func:`require_usable`); ``field`` names the
        shape in the error (e.g. ``scene.obstacles[2]``).
    """
    rotation = shape.axes
    center = np.array(shape.center, dtype=float)
    offset = np.zeros(3)
    if isinstance(shape, Box):
        geometry, half = fcl.Box(*shape.size), np.array(shape.size) / 2
    elif isinstance(shape, Cylinder):
        geometry = fcl.Cylinder(shape.radius, shape.height)
        half = np.array([shape.radius, shape.radius, shape.height / 2])
    elif isinstance(shape, Sphere):
        geometry, half = fcl.Sphere(shape.radius), np.full(3, shape.radius)
    else:
        geometry, low, high = _mesh_model(*shape.triangles(base_dir), field or name, name)
        offset, half = (low + high) / 2, (high - low) / 2
    body = Body(name, geometry, center, rotation, center + rotation @ offset, half)
    require_usable(body, field or name)
    return body


def require_triangles(vertices: NDArray, faces: NDArray, field: str, name: str) -> None:
    """Refuse a mesh with a non-finite vertex or no triangle of positive area: fcl would
    never report a contact with it."""
    vertices = np.asarray(vertices, dtype=float)
    faces = np.asarray(faces, dtype=int).reshape(-1, 3)
    if not np.all(np.isfinite(vertices)):
        _unusable(field, name, "a vertex is not finite")
    if len(faces) and faces.min() >= 0 and faces.max() < len(vertices):
        corners = vertices[faces]
        normals = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
        if np.any(np.linalg.norm(normals, axis=1) > 0.0):
            return
    _unusable(field, name, "it has no triangle of positive area")


def require_usable(body: Body, field: str) -> None:
    """Refuse a body whose pose or box is not finite or extends beyond USABLE_EXTENT."""
    numbers = np.concatenate([body.center, body.rotation.ravel(), body.box_center, body.half_size])
    if not np.all(np.isfinite(numbers)):
        _unusable(field, body.name, "its pose or size is not finite")
    if np.abs(body.box_center).max() + body.half_size.max() > USABLE_EXTENT:
        _unusable(field, body.name, f"it extends beyond {USABLE_EXTENT:g} m from the origin")


def _unusable(field: str, name: str, reason: str) -> NoReturn:
    raise CollisionBodyError(
        [FieldProblem(field, f"{name}: the collision checker cannot use it: {reason}")]
    )


def platform_prism(system: CableSystem, thickness: float) -> tuple[NDArray, NDArray]:
    """The platform as a thin prism through the convex hull of the points B'_i (in z'):
    vertices (2 n, 3) in the platform frame [m] and triangles (F, 3) indexing them."""
    points = np.unique(np.round(system.platform_points, 12), axis=0)
    centroid = points.mean(axis=0)
    angle = np.arctan2(points[:, 1] - centroid[1], points[:, 0] - centroid[0])
    ring = points[np.argsort(angle)]
    n = len(ring)
    top, bottom = ring + [0, 0, thickness / 2], ring - [0, 0, thickness / 2]
    vertices = np.concatenate([top, bottom])
    faces = [(0, i, i + 1) for i in range(1, n - 1)]
    faces += [(n, n + i + 1, n + i) for i in range(1, n - 1)]
    for i in range(n):
        j = (i + 1) % n
        faces += [(i, n + i, n + j), (i, n + j, j)]
    return vertices, np.array(faces)


def platform_body(system: CableSystem, thickness: float) -> Body:
    """The platform's collision body (:func:`platform_prism`)."""
    vertices, faces = platform_prism(system, thickness)
    low, high = vertices.min(axis=0), vertices.max(axis=0)
    return Body(
        "platform",
        _bvh(vertices, faces),
        np.zeros(3),
        np.eye(3),
        (low + high) / 2,
        (high - low) / 2,
    )


def obstacle_bodies(scene: SceneSpec, base_dir: Path | None) -> list[Body]:
    """The scene's obstacles grown by its clearance (meshes keep it as their ``margin``),
    placed once in the world (ground excluded); names and indices are the scene's."""
    bodies = []
    for index, shape in enumerate(scene.grown_obstacles()):
        name = scene.obstacle_name(index)
        body = body_from_shape(shape, name, base_dir, f"scene.obstacles[{index}]")
        placed = fcl.CollisionObject(body.geometry, fcl.Transform(body.rotation, body.center))
        margin = scene.collision.obstacle_clearance if isinstance(shape, Mesh) else 0.0
        bodies.append(
            Body(
                body.name,
                body.geometry,
                body.center,
                body.rotation,
                body.box_center,
                body.half_size + margin,
                placed,
                margin,
            )
        )
    return bodies


def payload_bodies(scene: SceneSpec, base_dir: Path | None) -> list[Body]:
    """The payload's shapes, posed in the platform frame."""
    return [
        body_from_shape(
            shape,
            shape.name or f"payload {shape.kind} {index + 1}",
            base_dir,
            f"scene.payload.shapes[{index}]",
        )
        for index, shape in enumerate(scene.payload.shapes)
    ]


def rotations_from_z(direction: NDArray[np.float64]) -> NDArray[np.float64]:
    """Rotations taking the z axis onto unit vectors, (..., 3) -> (..., 3, 3) (Rodrigues).

    Used to pose fcl capsules, whose axis is their local z. Directions within 1e-9 of -z
    take a half turn about x.
    """
    d = np.asarray(direction, dtype=float)
    c = d[..., 2]
    v = np.stack([-d[..., 1], d[..., 0], np.zeros_like(c)], axis=-1)  # z x d
    k = np.zeros(d.shape[:-1] + (3, 3))
    k[..., 0, 2], k[..., 1, 2], k[..., 2, 0], k[..., 2, 1] = (
        v[..., 1],
        -v[..., 0],
        -v[..., 1],
        v[..., 0],
    )
    k[..., 0, 1], k[..., 1, 0] = -v[..., 2], v[..., 2]
    flipped = c < -1.0 + 1e-9
    scale = np.where(flipped, 0.0, 1.0 / np.where(flipped, 1.0, 1.0 + c))
    r = np.eye(3) + k + (k @ k) * scale[..., None, None]
    r[flipped] = np.diag([1.0, -1.0, -1.0])
    return r
