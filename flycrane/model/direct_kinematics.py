"""Direct kinematics of the cable system: the configuration q from the three drone positions.

Used to check flown missions: given the drones' positions (telemetry), where is the platform?
The pose (p, R) solves the six cable-length equations ``|A_k(i) - p - R B'_i| = l_i``
by Newton's method. Their derivative with respect to a pose twist (dp, dw), with R updated
as exp([dw]) R, is ``-J^T`` -- the screw Jacobian of the statics -- so the iteration is
``J^T delta = r``, well posed exactly where the statics are (non-singular J). The alphas then
follow from each drone's position about its edge.

The equations have several solutions (e.g. the platform mirrored above the drones); the
iteration starts from ``initial`` when given (the planned configuration, in practice) and
otherwise from the rigid fit (Kabsch) of the drone triangle at alpha = 1 rad onto the
measured one, which lies in the hanging branch.

This is the readable reference; the timing tolerance, which solves some 60 simulated
flights per task, uses the compiled kernel in :mod:`flycrane.model.direct_kinematics_kernel`,
which the tests compare against it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from flycrane.errors import ConfigurationError, FieldProblem
from flycrane.model.cable_system import CableSystem
from flycrane.model.kinematics import (
    as_configurations,
    cable_vectors,
    drone_positions_in_platform_frame,
    matrix_from_tilt_torsion,
    tilt_torsion_from_matrix,
)
from flycrane.model.statics import screw_jacobian_from_points, singular_jacobians

#: Converged when every cable-length residual is below this [m]: 0.1 nm, far below any
#: position measurement, yet reached in a few Newton steps from a hanging-branch start.
LENGTH_TOLERANCE = 1e-10


@dataclass(frozen=True)
class DirectKinematicsResult:
    """Configurations reconstructed from drone positions."""

    q: NDArray[np.float64]  #: (N, 9)
    length_error: NDArray[np.float64]  #: (N, 6) |A - b| - l after the solve [m]
    converged: NDArray[np.bool_]  #: (N,) every |length_error| <= LENGTH_TOLERANCE


def _rotation_from_vector(w: NDArray[np.float64]) -> NDArray[np.float64]:
    """Rodrigues: exp([w]) for rotation vectors w, (N, 3) -> (N, 3, 3)."""
    angle = np.linalg.norm(w, axis=-1)[:, None, None]
    k = np.zeros(w.shape[:-1] + (3, 3))
    k[:, 0, 1], k[:, 0, 2], k[:, 1, 2] = -w[:, 2], w[:, 1], -w[:, 0]
    k -= k.transpose(0, 2, 1)
    safe = np.where(angle > 1e-12, angle, 1.0)
    a = np.where(angle > 1e-12, np.sin(safe) / safe, 1.0)
    b = np.where(angle > 1e-12, (1 - np.cos(safe)) / safe**2, 0.5)
    return np.eye(3) + a * k + b * k @ k


def _rigid_fit(local: NDArray, world: NDArray) -> tuple[NDArray, NDArray]:
    """Least-squares (p, R) with world ~ p + R local (Kabsch), points on axis -2."""
    lc, wc = local.mean(axis=-2, keepdims=True), world.mean(axis=-2, keepdims=True)
    h = np.swapaxes(local - lc, -1, -2) @ (world - wc)
    u, _, vt = np.linalg.svd(h)
    d = np.sign(np.linalg.det(np.swapaxes(vt, -1, -2) @ np.swapaxes(u, -1, -2)))
    fix = np.ones(h.shape[:-1])
    fix[..., -1] = d
    r = np.swapaxes(vt, -1, -2) @ (fix[..., None] * np.swapaxes(u, -1, -2))
    return (wc - lc @ np.swapaxes(r, -1, -2))[..., 0, :], r


def check_drone_positions(drones: ArrayLike) -> NDArray[np.float64]:
    """Drone positions (N, 3, 3) or (3, 3) as a finite (N, 3, 3) array, else an error."""
    a = np.asarray(drones, dtype=float)
    if a.ndim == 2:
        a = a[None]
    if a.ndim != 3 or a.shape[1:] != (3, 3) or not np.all(np.isfinite(a)):
        raise ConfigurationError(
            [FieldProblem("drones", f"expected finite (N, 3, 3) positions, got {np.shape(drones)}")]
        )
    return a


def result_from_pose(
    system: CableSystem,
    drones: NDArray[np.float64],
    p: NDArray[np.float64],
    r: NDArray[np.float64],
    residual: NDArray[np.float64],
) -> DirectKinematicsResult:
    """The result of a solved pose p (N, 3), R (N, 3, 3): the alphas follow from each drone's
    position about its edge; ``residual`` (N, 6) is the solve's last length error."""
    relative = np.einsum("nba,nkb->nka", r, drones - p[:, None, :]) - system.drone_foot
    alpha = np.arctan2(
        np.einsum("nka,ka->nk", relative, system.drone_up),
        np.einsum("nka,ka->nk", relative, system.drone_outward),
    )
    q = np.concatenate([p, tilt_torsion_from_matrix(r), alpha], axis=1)
    return DirectKinematicsResult(
        q=q, length_error=residual, converged=np.all(np.abs(residual) <= LENGTH_TOLERANCE, 1)
    )


def configuration_from_drone_positions(
    system: CableSystem,
    drones: ArrayLike,
    initial: ArrayLike | None = None,
    max_iterations: int = 50,
) -> DirectKinematicsResult:
    """Solve the direct kinematics for drone positions of shape (N, 3, 3) or (3, 3).

    Parameters
    ----------
    drones : array-like
        World positions of drones 1..3 [m].
    initial : array-like, optional
        Configurations (N, 9) to start from, selecting the solution branch.
    """
    a = check_drone_positions(drones)
    if initial is None:
        p, r = _rigid_fit(drone_positions_in_platform_frame(system, np.ones((len(a), 3))), a)
    else:
        start = as_configurations(initial, "initial")
        p, r = start[:, :3].copy(), matrix_from_tilt_torsion(start[:, 3:6])
    residual = np.zeros((len(a), 6))
    for _ in range(max_iterations):
        b = p[:, None, :] + np.einsum("nab,ib->nia", r, system.platform_points)
        residual = np.linalg.norm(cable_vectors(b, a), axis=-1) - system.cable_lengths
        if np.all(np.abs(residual) <= LENGTH_TOLERANCE):
            break
        # Cable directions towards the *measured* drones, where the residual is taken.
        jac = screw_jacobian_from_points(p, b, a)
        # Rows with singular J keep their pose: the direct kinematics is ill-posed there,
        # and their residual reports it (converged False).
        regular = ~singular_jacobians(jac)
        step = np.zeros((len(a), 6))
        step[regular] = np.linalg.solve(
            np.swapaxes(jac[regular], -1, -2), residual[regular, :, None]
        )[..., 0]
        p = p + step[:, :3]
        r = _rotation_from_vector(step[:, 3:]) @ r
    return result_from_pose(system, a, p, r, residual)
