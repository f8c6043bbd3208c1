"""Statics of the FlyCrane (design.md section 5; paper section III-B, eq. 3-7).

Readable numpy reference of every formula, vectorized over ``(N, 9)`` configurations. The
planner's hot path uses the compiled kernel in :mod:`flycrane.model.statics_kernel`, which is
tested against these functions.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from flycrane.model.cable_system import CABLE_DRONE, CableSystem
from flycrane.model.kinematics import Poses, cable_vectors, forward_kinematics
from flycrane.model.system_spec import DRONE_CABLES

#: J counts as singular below this Hadamard ratio |det J| / prod(column norms) (1 for
#: orthogonal columns). At 1e-12 a solve loses about 12 of 16 digits and the tensions it
#: implies exceed any cable's rating by orders of magnitude, so nothing feasible is lost.
SINGULARITY_THRESHOLD = 1e-12


def screw_jacobian(poses: Poses) -> NDArray[np.float64]:
    """Screw Jacobian ``J[:, i] = [u_i ; (b_i - p) x u_i]`` at P in world axes, (N, 6, 6)."""
    return screw_jacobian_from_points(poses.q[:, :3], poses.platform_points, poses.drones)


def screw_jacobian_from_points(
    position: NDArray[np.float64], platform: NDArray[np.float64], drones: NDArray[np.float64]
) -> NDArray[np.float64]:
    """Screw Jacobian from P (N, 3), the points b_i (N, 6, 3) and the drones A_k (N, 3, 3),
    where they do not come from a configuration (the direct kinematics' iterates)."""
    u = cable_vectors(platform, drones)
    u /= np.linalg.norm(u, axis=-1, keepdims=True)
    moment = np.cross(platform - position[:, None, :], u)
    return np.concatenate([u, moment], axis=-1).transpose(0, 2, 1)


def nominal_wrench(system: CableSystem, rotation: NDArray[np.float64]) -> NDArray[np.float64]:
    """Wrench the cables must supply, ``w0 = -[m g_vec ; c x (m g_vec)]``, shape (N, 6), for
    platform orientations R (N, 3, 3)."""
    weight = np.array([0.0, 0.0, -system.platform_mass * system.gravity])
    c = rotation @ system.com_offset
    return -np.concatenate([np.broadcast_to(weight, c.shape), np.cross(c, weight)], axis=-1)


def singular_jacobians(jacobian: NDArray[np.float64]) -> NDArray[np.bool_]:
    """True where J is (numerically) singular, by the Hadamard ratio test, shape (N,)."""
    norms = np.prod(np.linalg.norm(jacobian, axis=1), axis=-1)
    return np.abs(np.linalg.det(jacobian)) <= SINGULARITY_THRESHOLD * norms


def nominal_tensions(jacobian: NDArray[np.float64], wrench: NDArray[np.float64]) -> NDArray:
    """f0 = J^-1 w0 (eq. 3), shape (N, 6). J must be non-singular."""
    return np.linalg.solve(jacobian, wrench[..., None])[..., 0]


def tension_half_widths(system: CableSystem, jacobian: NDArray[np.float64]) -> NDArray:
    """v_ii = sqrt((J^-1 E^-1 J^-T)_ii), the half width of each tension range (eq. 4-6).

    Computed as the row norms of J^-1 L with L L^T = E^-1, which is that diagonal.
    """
    x = np.linalg.solve(jacobian, np.broadcast_to(system.perturbation_sqrt, jacobian.shape))
    return np.linalg.norm(x, axis=-1)


def thrust_vectors(
    system: CableSystem,
    poses: Poses,
    tensions: NDArray[np.float64],
) -> NDArray[np.float64]:
    """Thrust each drone must supply, ``T_k = -(M_k g_vec + f_i w_i + f_j w_j)`` (eq. 7).

    w_i is the unit vector from the drone to its platform point. ``tensions`` is (N, 6),
    giving (N, 3, 3), or (N, 6, C) for C tension vectors at once, giving (N, 3, 3, C).
    """
    w = -poses.cables / system.cable_lengths[:, None]
    stacked = tensions if tensions.ndim == 3 else tensions[..., None]
    pull = w[..., None] * stacked[:, :, None, :]  # (N, 6, 3, C)
    first, second = np.array(DRONE_CABLES).T
    weight = np.zeros((3, 3, 1))
    weight[:, 2, 0] = -system.drone_masses * system.gravity
    thrust = -(weight + pull[:, first] + pull[:, second])
    return thrust if tensions.ndim == 3 else thrust[..., 0]


def thrust_bounds(
    system: CableSystem,
    poses: Poses,
    f0: NDArray[np.float64],
    half_width: NDArray[np.float64],
) -> NDArray[np.float64]:
    """m_k = max |T_k| over the box (lam_i, lam_j) in [-v_ii, v_ii] x [-v_jj, v_jj] (eq. 7).

    |T_k| is convex in (lam_i, lam_j), so the maximum is at one of the four corners.
    Returns shape (N, 3).
    """
    signs = np.array([[-1, -1], [-1, 1], [1, -1], [1, 1]], dtype=float).T  # (2, 4)
    corners = np.repeat(f0[:, :, None], 4, axis=2)
    for i, j in DRONE_CABLES:
        corners[:, i] += signs[0] * half_width[:, i, None]
        corners[:, j] += signs[1] * half_width[:, j, None]
    return np.linalg.norm(thrust_vectors(system, poses, corners), axis=2).max(axis=-1)


@dataclass(frozen=True)
class StaticsReport:
    """Statics of N configurations. Singular rows hold +/-inf, never NaN.

    Tensions in N, indexed by cable (0-based arrays; cable i + 1 in messages).
    """

    q: NDArray[np.float64]  #: (N, 9)
    singular: NDArray[np.bool_]  #: (N,) J numerically singular
    nominal_tension: NDArray[np.float64]  #: (N, 6) f0 (+inf where singular)
    half_width: NDArray[np.float64]  #: (N, 6) v_ii (+inf where singular)
    tension_low: NDArray[np.float64]  #: (N, 6) t_lo = f0 - v (-inf where singular)
    tension_high: NDArray[np.float64]  #: (N, 6) t_hi = f0 + v (+inf where singular)
    nominal_thrust: NDArray[np.float64]  #: (N, 3, 3) T_k at f0 (+inf where singular)
    thrust_bound: NDArray[np.float64]  #: (N, 3) m_k (+inf where singular)
    slack_margin: NDArray[np.float64]  #: (N, 6) t_lo - f_lo
    overload_margin: NDArray[np.float64]  #: (N, 6) f_hi - t_hi
    thrust_margin: NDArray[np.float64]  #: (N, 3) h - m

    @property
    def feasible(self) -> NDArray[np.bool_]:
        """Wrench- and thrust-feasible (every margin > 0), shape (N,)."""
        return (
            ~self.singular
            & np.all(self.slack_margin > 0, axis=1)
            & np.all(self.overload_margin > 0, axis=1)
            & np.all(self.thrust_margin > 0, axis=1)
        )


def evaluate_statics(system: CableSystem, q: ArrayLike) -> StaticsReport:
    """Tensions, tension ranges, thrusts and margins of configurations (eq. 3-7)."""
    poses = forward_kinematics(system, q)
    q, n = poses.q, len(poses.q)
    jacobian = screw_jacobian(poses)
    singular = singular_jacobians(jacobian)
    regular = ~singular
    f0 = np.full((n, 6), np.inf)
    v = np.full((n, 6), np.inf)
    thrust = np.full((n, 3, 3), np.inf)
    bound = np.full((n, 3), np.inf)
    if regular.any():
        jr, pr = jacobian[regular], poses.rows(regular)
        f0[regular] = nominal_tensions(jr, nominal_wrench(system, pr.rotation))
        v[regular] = tension_half_widths(system, jr)
        thrust[regular] = thrust_vectors(system, pr, f0[regular])
        bound[regular] = thrust_bounds(system, pr, f0[regular], v[regular])
    low = np.full((n, 6), -np.inf)
    low[regular] = f0[regular] - v[regular]
    high = f0 + v
    return StaticsReport(
        q=q,
        singular=singular,
        nominal_tension=f0,
        half_width=v,
        tension_low=low,
        tension_high=high,
        nominal_thrust=thrust,
        thrust_bound=bound,
        slack_margin=low - system.tension_min,
        overload_margin=system.tension_max - high,
        thrust_margin=system.max_thrusts - bound,
    )


__all__ = [
    "CABLE_DRONE",
    "SINGULARITY_THRESHOLD",
    "StaticsReport",
    "evaluate_statics",
    "nominal_tensions",
    "nominal_wrench",
    "screw_jacobian",
    "screw_jacobian_from_points",
    "singular_jacobians",
    "tension_half_widths",
    "thrust_bounds",
    "thrust_vectors",
]
