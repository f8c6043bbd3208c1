"""Extent of the robot's collision bodies along a world direction (design.md section 6).

The bodies are the ones the collision model checks: the drones (spheres at A_k), the six
cables (capsules b_i -> A_i), the platform (the thin prism through the B'_i) and the
payload's shapes. Each body's extent along a unit direction d is the interval of its
support function, ``[min_x x.d, max_x x.d]``, in closed form:

- sphere or capsule: the centre (the segment's end points) projected, +/- the radius;
- box with world axes R and half sizes h: ``c.d +/- sum_j |(R^T d)_j| h_j``;
- cylinder with world axis a, radius r, half height k: ``c.d +/- (k |a.d| + r sqrt(1 - (a.d)^2))``;
- prism or mesh: its vertices projected (the extent of a polytope is its vertices').

So a configuration fits between two parallel walls normal to d exactly when the walls
are further apart than the width ``high - low`` (with the formation placed between them):
this is the across-corridor width of the corridor benchmark (issue 12). The scene's
``obstacle_clearance`` grows the walls, not these bodies.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike, NDArray

from flycrane.errors import FieldProblem, InputError
from flycrane.model.cable_system import CableSystem
from flycrane.model.kinematics import (
    as_configurations,
    drone_positions_from_configuration,
    matrix_from_tilt_torsion,
    platform_points_from_configuration,
)
from flycrane.model.system_spec import DRONE_CABLES
from flycrane.world.bodies import platform_prism
from flycrane.world.scene import Box, Cylinder, SceneSpec, Sphere


def _unit(direction: ArrayLike) -> NDArray[np.float64]:
    d = np.asarray(direction, dtype=float)
    norm = float(np.linalg.norm(d)) if d.shape == (3,) else 0.0
    if not np.isfinite(norm) or norm == 0.0:
        raise InputError(
            [FieldProblem("direction", f"need a finite non-zero (3,) vector, got {d.tolist()}")]
        )
    return d / norm


def extent_from_configuration(
    system: CableSystem,
    scene: SceneSpec,
    q: ArrayLike,
    direction: ArrayLike = (0.0, 1.0, 0.0),
    base_dir: Path | None = None,
) -> NDArray[np.float64]:
    """Least and greatest projection of the robot's collision bodies on a direction.

    Parameters
    ----------
    system : CableSystem
    scene : SceneSpec
        Gives the payload's shapes and the body sizes (``scene.collision``).
    q : array-like, shape (9,) or (N, 9)
        Configurations (design.md s.3).
    direction : array-like, shape (3,)
        World direction; normalized here. Default: world y, across the corridor.
    base_dir : Path, optional
        Where the payload's mesh files are (as for the collision checker).

    Returns
    -------
    extent : ndarray, shape (N, 2)
        (low, high) [m] along the direction, over all bodies.

    Raises
    ------
    InputError
        If the direction is not a finite non-zero 3-vector.
    ConfigurationError
        If q is not a valid array of configurations.
    """
    d = _unit(direction)
    q = as_configurations(q)
    settings = scene.collision
    rotation = matrix_from_tilt_torsion(q[:, 3:6])  # (N, 3, 3)
    position = q[:, :3] @ d  # (N,)
    local_d = np.einsum("nab,a->nb", rotation, d)  # d in the platform frame, (N, 3)

    drones = drone_positions_from_configuration(system, q) @ d  # (N, 3)
    starts = platform_points_from_configuration(system, q) @ d  # (N, 6)
    ends = drones[:, [k for k, pair in enumerate(DRONE_CABLES) for _ in pair]]
    lows = [drones - settings.drone_radius, np.minimum(starts, ends) - settings.cable_radius]
    highs = [drones + settings.drone_radius, np.maximum(starts, ends) + settings.cable_radius]

    prism, _ = platform_prism(system, settings.platform_thickness)
    projected = position[:, None] + local_d @ prism.T  # (N, V)
    lows.append(projected.min(axis=1, keepdims=True))
    highs.append(projected.max(axis=1, keepdims=True))

    for shape in scene.payload.shapes:
        axes = shape.axes  # shape frame in platform
        center = position + local_d @ np.array(shape.center)
        along = local_d @ axes  # d in the shape's frame, (N, 3)
        if isinstance(shape, Box):
            half = np.abs(along) @ (np.array(shape.size) / 2)
        elif isinstance(shape, Cylinder):
            cos = np.clip(np.abs(along[:, 2]), 0.0, 1.0)
            half = shape.height / 2 * cos + shape.radius * np.sqrt(1.0 - cos**2)
        elif isinstance(shape, Sphere):
            half = np.full(len(q), shape.radius)
        else:
            vertices, _ = shape.triangles(base_dir)
            projected = center[:, None] + along @ vertices.T
            lows.append(projected.min(axis=1, keepdims=True))
            highs.append(projected.max(axis=1, keepdims=True))
            continue
        lows.append((center - half)[:, None])
        highs.append((center + half)[:, None])

    low = np.concatenate(lows, axis=1).min(axis=1)
    high = np.concatenate(highs, axis=1).max(axis=1)
    return np.stack([low, high], axis=1)


def width_from_configuration(
    system: CableSystem,
    scene: SceneSpec,
    q: ArrayLike,
    direction: ArrayLike = (0.0, 1.0, 0.0),
    base_dir: Path | None = None,
) -> NDArray[np.float64]:
    """Width [m] of the robot's collision bodies along a direction, shape (N,).

    The least gap between two walls normal to ``direction`` that the configuration fits
    (:func:`extent_from_configuration`, whose parameters these are).
    """
    extent = extent_from_configuration(system, scene, q, direction, base_dir)
    return extent[:, 1] - extent[:, 0]
