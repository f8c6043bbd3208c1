"""How far the platform's points move when the drones are off their positions: the
linearized direct kinematics, and a bound on the displacement from bounds on the drones'
errors (the paper's future work: robustness to the drones' errors).

With the cables taut, cable i (drone k = CABLE_DRONE[i], platform point b_i = p + R B'_i,
unit vector u_i from b_i to A_k) keeps its length: to first order
``u_i . dA_k = u_i . dp + ((b_i - p) x u_i) . dw``, that is ``J^T dx = M da`` with J the
screw Jacobian of the statics (design.md eq. 2), dx = (dp, dw) the platform's twist and M
(6 x 9) the cables' unit vectors at their drones' columns. So ``dx = G da`` with
``G = J^-T M`` (:func:`pose_sensitivity`), defined exactly where the statics are
(non-singular J).

A platform point at r from P (world axes) moves by ``dp + dw x r = L da``, L = [I, -[r]x] G,
whose three 3 x 3 blocks L_k say how drone k's error moves it. Drone errors come as a
*common* part c, shared by the three (a rigid shift: the point moves by c), and each
drone's own part e_k within a horizontal radius h and a vertical half-height v. The point's
displacement is then at most (:func:`displacement_bound`)

    |c| + sum_k (||L_k[:, :2]|| h + ||L_k[:, 2]|| v),

the spectral norm of each block's horizontal columns and the norm of its vertical one: the
triangle inequality over the drones, exact for one drone, and a bound for three
(``tests/flycrane/model/test_pose_error.py`` holds it against the exact direct kinematics
of sampled errors). Its assumptions: taut cables (the statics' feasibility), errors small
against the cables (first order), and the drones' errors independent within their bounds.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from flycrane.model.cable_system import CABLE_DRONE, CableSystem
from flycrane.model.kinematics import Poses, forward_kinematics
from flycrane.model.statics import screw_jacobian


def pose_sensitivity(poses: Poses) -> NDArray[np.float64]:
    """G = d(p, w) / d(A_1, A_2, A_3) at N poses: (N, 6, 9), the platform's twist per metre
    of each drone coordinate (module docstring)."""
    jacobian = screw_jacobian(poses)  # (N, 6, 6)
    u = poses.cables
    u /= np.linalg.norm(u, axis=-1, keepdims=True)
    m = np.zeros((len(poses.q), 6, 9))
    for i, k in enumerate(CABLE_DRONE):
        m[:, i, 3 * k : 3 * k + 3] = u[:, i]
    return np.asarray(np.linalg.solve(np.transpose(jacobian, (0, 2, 1)), m), dtype=np.float64)


def point_sensitivity(system: CableSystem, q: ArrayLike, points: ArrayLike) -> NDArray[np.float64]:
    """L = d(point) / d(drones) of platform-frame points (P, 3) at configurations q (N, 9):
    (N, P, 3, 9)."""
    poses = forward_kinematics(system, q)
    r = np.einsum("nab,pb->npa", poses.rotation, np.asarray(points, dtype=float).reshape(-1, 3))
    g = pose_sensitivity(poses)
    # dp + dw x r = dp - r x dw
    cross = np.zeros(r.shape + (3,))
    cross[..., 0, 1], cross[..., 0, 2], cross[..., 1, 2] = -r[..., 2], r[..., 1], -r[..., 0]
    cross -= np.swapaxes(cross, -1, -2)
    return g[:, None, :3, :] - cross @ g[:, None, 3:, :]


def displacement_bound(
    system: CableSystem,
    q: ArrayLike,
    points: ArrayLike,
    common: tuple[float, float],
    own: tuple[float, float],
) -> NDArray[np.float64]:
    """Bound on the displacement [m] of platform-frame points (P, 3) at configurations q
    (N, 9) when the drones share an error within ``common`` (horizontal, vertical) and each
    has its own within ``own`` (horizontal radius, vertical half-height): (N, P) (module
    docstring)."""
    blocks = _drone_blocks(system, q, points)
    horizontal = np.linalg.norm(blocks[..., :2], ord=2, axis=(-3, -1))  # (N, P, drone)
    vertical = np.linalg.norm(blocks[..., 2], axis=-2)  # (N, P, drone)
    own_part = (horizontal * own[0] + vertical * own[1]).sum(axis=-1)
    return float(np.hypot(*common)) + own_part


def height_bound(
    system: CableSystem,
    q: ArrayLike,
    points: ArrayLike,
    common_vertical: float,
    own: tuple[float, float],
) -> NDArray[np.float64]:
    """Bound on the vertical displacement [m] of platform-frame points (P, 3) at
    configurations q (N, 9), what a clearance above a horizontal surface must cover:
    ``c_v + sum_k (||L_k[2, :2]|| h + |L_k[2, 2]| v)``, the height row of
    :func:`displacement_bound`'s sum: (N, P)."""
    rows = _drone_blocks(system, q, points)[..., 2, :, :]  # (N, P, drone, coord)
    own_part = np.linalg.norm(rows[..., :2], axis=-1) * own[0] + np.abs(rows[..., 2]) * own[1]
    return common_vertical + own_part.sum(axis=-1)


def _drone_blocks(system: CableSystem, q: ArrayLike, points: ArrayLike) -> NDArray[np.float64]:
    """:func:`point_sensitivity` by drone: (N, P, 3, drone, coordinate)."""
    sensitivity = point_sensitivity(system, q, points)
    return sensitivity.reshape(sensitivity.shape[:-1] + (3, 3))
