"""Kinematics of the FlyCrane (design.md sections 3-4; paper eq. 1-2).

A configuration is ``q = (x, y, z, phi, theta, sigma, alpha1, alpha2, alpha3)``. Every public
function takes an ``(N, 9)`` array (a single ``(9,)`` configuration is the N = 1 case and is
returned with the leading axis kept) and is vectorized over N.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from flycrane.errors import ConfigurationError, FieldProblem
from flycrane.model.cable_system import CABLE_DRONE, CableSystem

#: Names of the nine configuration coordinates, in order.
COORDINATES = ("x", "y", "z", "phi", "theta", "sigma", "alpha1", "alpha2", "alpha3")


def as_configurations(q: ArrayLike, name: str = "q") -> NDArray[np.float64]:
    """Check and convert configurations to a float ``(N, 9)`` array.

    Raises
    ------
    ConfigurationError
        If the shape is not ``(9,)`` or ``(N, 9)``, a value is not finite, or a tilt theta is
        outside [0, pi] (the tilt-and-torsion chart; a negative tilt is phi + pi).
    """
    try:
        array = np.asarray(q, dtype=float)
    except (TypeError, ValueError) as error:
        raise ConfigurationError(
            [FieldProblem(name, f"not an array of numbers: {error}")]
        ) from None
    batch = array.ndim == 2  # a list of configurations: its rows are named by index
    if array.ndim == 1:
        array = array[None, :]
    if array.ndim != 2 or array.shape[1] != 9:
        raise ConfigurationError(
            [FieldProblem(name, f"expected shape (9,) or (N, 9), got {np.shape(q)}")]
        )
    problems = []
    bad_rows, bad_cols = np.nonzero(~np.isfinite(array))
    for row, col in zip(bad_rows[:5], bad_cols[:5], strict=True):
        problems.append(FieldProblem(_field(name, batch, row, col), "must be finite"))
    theta = array[:, 4]
    for row in np.flatnonzero((theta < 0.0) | (theta > np.pi))[:5]:
        problems.append(
            FieldProblem(_field(name, batch, row, 4), f"tilt {theta[row]:.6g} rad not in [0, pi]")
        )
    if problems:
        raise ConfigurationError(problems)
    return array


def _field(name: str, batch: bool, row: int, col: int) -> str:
    prefix = f"{name}[{row}]" if batch else name
    return f"{prefix}.{COORDINATES[col]}"


def matrix_from_tilt_torsion(angles: ArrayLike) -> NDArray[np.float64]:
    """Rotation matrices ``R = Rz(phi) Ry(theta) Rz(sigma - phi)`` (paper eq. 1).

    Parameters
    ----------
    angles : array-like, shape (..., 3)
        (phi, theta, sigma) [rad].

    Returns
    -------
    R : ndarray, shape (..., 3, 3)
    """
    angles = np.asarray(angles, dtype=float)
    phi, theta, sigma = angles[..., 0], angles[..., 1], angles[..., 2]
    cp, sp = np.cos(phi), np.sin(phi)
    ct, st = np.cos(theta), np.sin(theta)
    cs, ss = np.cos(sigma - phi), np.sin(sigma - phi)
    r = np.empty(angles.shape[:-1] + (3, 3))
    r[..., 0, 0] = cp * ct * cs - sp * ss
    r[..., 0, 1] = -cp * ct * ss - sp * cs
    r[..., 0, 2] = cp * st
    r[..., 1, 0] = sp * ct * cs + cp * ss
    r[..., 1, 1] = -sp * ct * ss + cp * cs
    r[..., 1, 2] = sp * st
    r[..., 2, 0] = -st * cs
    r[..., 2, 1] = st * ss
    r[..., 2, 2] = ct
    return r


def tilt_torsion_from_matrix(r: ArrayLike) -> NDArray[np.float64]:
    """Tilt-and-torsion angles (phi, theta, sigma) of rotation matrices, shape (..., 3).

    theta is in [0, pi], phi and sigma in (-pi, pi]. With psi = sigma - phi, the sums
    ``R00 + R11 = (1 + cos theta) cos(phi + psi)``, ``R10 - R01 = (1 + cos theta) sin(...)``
    give sigma well conditioned for theta < pi/2, and the differences
    ``R11 - R00 = (1 - cos theta) cos(phi - psi)``, ``R10 + R01 = (cos theta - 1) sin(...)``
    give phi - psi well conditioned for theta >= pi/2. Where the tilt axis is undefined
    (theta = 0 or pi) phi is returned as 0, the chart's choice.
    """
    r = np.asarray(r, dtype=float)
    # arctan2 of (sin, cos) keeps small tilts that arccos(R22) rounds to zero below ~1e-8 rad.
    sin_theta = np.hypot(r[..., 0, 2], r[..., 1, 2])
    theta = np.arctan2(sin_theta, r[..., 2, 2])
    # Any phi reproduces the rotation once sigma is derived from it below, so phi is only
    # pinned (to 0) where the tilt axis is exactly undefined.
    phi = np.where(sin_theta > 0.0, np.arctan2(r[..., 1, 2], r[..., 0, 2]), 0.0)
    total = np.arctan2(r[..., 1, 0] - r[..., 0, 1], r[..., 0, 0] + r[..., 1, 1])
    difference = np.arctan2(-(r[..., 1, 0] + r[..., 0, 1]), r[..., 1, 1] - r[..., 0, 0])
    sigma = np.where(r[..., 2, 2] > 0.0, total, 2.0 * phi - difference)
    return np.stack([phi, theta, np.angle(np.exp(1j * sigma))], axis=-1)


def drone_positions_in_platform_frame(system: CableSystem, alpha: ArrayLike) -> NDArray[np.float64]:
    """Drone positions a'_k in the platform frame for angles alpha, shape (N, 3) -> (N, 3, 3)."""
    alpha = np.asarray(alpha, dtype=float)
    ca, sa = np.cos(alpha)[..., None], np.sin(alpha)[..., None]
    return system.drone_foot + system.drone_radius[:, None] * (
        ca * system.drone_outward + sa * system.drone_up
    )


def _attachments(system: CableSystem, q: NDArray, r: NDArray) -> NDArray[np.float64]:
    """b_i = p + R B'_i of checked configurations (N, 9) with their orientations R."""
    return q[:, None, :3] + np.einsum("nab,ib->nia", r, system.platform_points)


def _drones(system: CableSystem, q: NDArray, r: NDArray) -> NDArray[np.float64]:
    """A_k = p + R a'_k(alpha_k) of checked configurations (N, 9) with their R."""
    local = drone_positions_in_platform_frame(system, q[:, 6:9])
    return q[:, None, :3] + np.einsum("nab,nkb->nka", r, local)


def platform_points_from_configuration(system: CableSystem, q: ArrayLike) -> NDArray[np.float64]:
    """World positions b_i = p + R B'_i of the six cable attachments, shape (N, 6, 3)."""
    q = as_configurations(q)
    return _attachments(system, q, matrix_from_tilt_torsion(q[:, 3:6]))


def drone_positions_from_configuration(system: CableSystem, q: ArrayLike) -> NDArray[np.float64]:
    """World drone positions A_k = p + R a'_k(alpha_k) (design.md eq. 2), shape (N, 3, 3)."""
    q = as_configurations(q)
    return _drones(system, q, matrix_from_tilt_torsion(q[:, 3:6]))


def cable_vectors(
    platform_points: NDArray[np.float64], drones: NDArray[np.float64]
) -> NDArray[np.float64]:
    """Vectors A_i - b_i from each platform point to its drone, shape (N, 6, 3)."""
    return drones[:, CABLE_DRONE, :] - platform_points


@dataclass(frozen=True)
class Poses:
    """Forward kinematics of N configurations, computed once for the formulas that read it
    (statics, pose error, tracks, logs)."""

    q: NDArray[np.float64]  #: (N, 9) the configurations
    rotation: NDArray[np.float64]  #: (N, 3, 3) the platform's orientation R (paper eq. 1)
    platform_points: NDArray[np.float64]  #: (N, 6, 3) cable attachments b_i
    drones: NDArray[np.float64]  #: (N, 3, 3) drone positions A_k (design.md eq. 2)

    @property
    def cables(self) -> NDArray[np.float64]:
        """Vectors A_i - b_i from each platform point to its drone, shape (N, 6, 3)."""
        return cable_vectors(self.platform_points, self.drones)

    def rows(self, index: NDArray[np.bool_] | NDArray[np.int64]) -> Poses:
        """The poses of the configurations ``q[index]``."""
        return Poses(
            self.q[index], self.rotation[index], self.platform_points[index], self.drones[index]
        )


def forward_kinematics(system: CableSystem, q: ArrayLike) -> Poses:
    """Orientation, attachment points and drones of configurations q, (9,) or (N, 9)."""
    q = as_configurations(q)
    r = matrix_from_tilt_torsion(q[:, 3:6])
    return Poses(q, r, _attachments(system, q, r), _drones(system, q, r))
