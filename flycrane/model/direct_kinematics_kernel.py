"""Compiled (numba) direct kinematics: the timing tolerance's hot path.

The same Newton iteration as :mod:`flycrane.model.direct_kinematics` (the readable reference,
which the tests compare this kernel against), one row at a time: the six cable-length
residuals at (p, R), the screw Jacobian's transpose ``J^T`` from the cable directions
towards the measured drones, ``J^T delta = r`` by Gaussian elimination with partial
pivoting, the pose updated as ``p += dp``, ``R = exp([dw]) R``. Rows differ from the
reference only in rounding, and in that each row stops at its own convergence instead of
stepping on until every row has converged.

Why compiled: the timing tolerance simulates some 60 flights of ~1,100 samples each per
task, and numpy's per-call cost on the small (N, 6, 6) arrays of every Newton step made
them a large share of a ``flycrane plan`` (BENCHMARKS.md, "``flycrane plan`` end to end",
"Fourth round").
"""

from __future__ import annotations

import math

import numba
import numpy as np
from numpy.typing import ArrayLike

from flycrane.model.cable_system import CABLE_DRONE, CableSystem
from flycrane.model.direct_kinematics import (
    LENGTH_TOLERANCE,
    DirectKinematicsResult,
    check_drone_positions,
    result_from_pose,
)
from flycrane.model.kinematics import as_configurations, matrix_from_tilt_torsion
from flycrane.model.statics import SINGULARITY_THRESHOLD
from flycrane.model.statics_kernel import back_substitute, eliminate

_CABLE_DRONE = np.array(CABLE_DRONE, dtype=np.int64)


@numba.njit(cache=True, nogil=True)
def _newton_row(drones, p, r, model, residual, max_iterations) -> None:
    """Solve one row in place: p (3,) and R (3, 3) from the start, residual (6,) out.
    ``model`` is :func:`_model`'s tuple."""
    points, cable_drone, lengths, tolerances = model
    length_tolerance, singularity_threshold = tolerances[0], tolerances[1]
    rows = np.empty((6, 6))  # J^T: row i is [u_i, (b_i - p) x u_i]
    rhs = np.empty((6, 1))
    rotation = np.empty((3, 3))
    for _ in range(max_iterations):
        converged = True
        column_norms = 1.0
        for i in range(6):
            arm0 = r[0, 0] * points[i, 0] + r[0, 1] * points[i, 1] + r[0, 2] * points[i, 2]
            arm1 = r[1, 0] * points[i, 0] + r[1, 1] * points[i, 1] + r[1, 2] * points[i, 2]
            arm2 = r[2, 0] * points[i, 0] + r[2, 1] * points[i, 1] + r[2, 2] * points[i, 2]
            k = cable_drone[i]
            d0 = drones[k, 0] - p[0] - arm0
            d1 = drones[k, 1] - p[1] - arm1
            d2 = drones[k, 2] - p[2] - arm2
            length = math.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
            residual[i] = length - lengths[i]
            if abs(residual[i]) > length_tolerance:
                converged = False
            u0, u1, u2 = d0 / length, d1 / length, d2 / length
            rows[i, 0], rows[i, 1], rows[i, 2] = u0, u1, u2
            rows[i, 3] = arm1 * u2 - arm2 * u1
            rows[i, 4] = arm2 * u0 - arm0 * u2
            rows[i, 5] = arm0 * u1 - arm1 * u0
            column_norms *= math.sqrt(1.0 + rows[i, 3] ** 2 + rows[i, 4] ** 2 + rows[i, 5] ** 2)
            rhs[i, 0] = residual[i]
        if converged:
            return
        det = eliminate(rows, rhs)  # det(J^T) = det(J)
        # A singular J keeps the pose, as in the reference: the residual reports it.
        if abs(det) <= singularity_threshold * column_norms:
            return
        back_substitute(rows, rhs)
        p[0] += rhs[0, 0]
        p[1] += rhs[1, 0]
        p[2] += rhs[2, 0]
        # R = exp([w]) R by Rodrigues, with its series limit at w = 0 as in the reference.
        w0, w1, w2 = rhs[3, 0], rhs[4, 0], rhs[5, 0]
        angle = math.sqrt(w0 * w0 + w1 * w1 + w2 * w2)
        a, b = 1.0, 0.5
        if angle > 1e-12:
            a, b = math.sin(angle) / angle, (1.0 - math.cos(angle)) / angle**2
        rotation[0, 0] = 1.0 - b * (w1 * w1 + w2 * w2)
        rotation[0, 1] = -a * w2 + b * w0 * w1
        rotation[0, 2] = a * w1 + b * w0 * w2
        rotation[1, 0] = a * w2 + b * w0 * w1
        rotation[1, 1] = 1.0 - b * (w0 * w0 + w2 * w2)
        rotation[1, 2] = -a * w0 + b * w1 * w2
        rotation[2, 0] = -a * w1 + b * w0 * w2
        rotation[2, 1] = a * w0 + b * w1 * w2
        rotation[2, 2] = 1.0 - b * (w0 * w0 + w1 * w1)
        for j in range(3):
            c0, c1, c2 = r[0, j], r[1, j], r[2, j]
            for i in range(3):
                r[i, j] = rotation[i, 0] * c0 + rotation[i, 1] * c1 + rotation[i, 2] * c2


@numba.njit(cache=True, nogil=True)
def _newton_rows(drones, p, r, model, residual, max_iterations) -> None:
    for n in range(drones.shape[0]):
        _newton_row(drones[n], p[n], r[n], model, residual[n], max_iterations)


def _model(system: CableSystem) -> tuple:
    """The system's constants as the tuple :func:`_newton_row` takes. The tolerances are
    passed, not read as globals: numba freezes globals into its cache, which a change in
    another module does not invalidate."""
    return (
        np.ascontiguousarray(system.platform_points),
        _CABLE_DRONE,
        np.ascontiguousarray(system.cable_lengths),
        np.array([LENGTH_TOLERANCE, SINGULARITY_THRESHOLD]),
    )


def compiled_direct_kinematics(
    system: CableSystem, drones: ArrayLike, initial: ArrayLike, max_iterations: int = 50
) -> DirectKinematicsResult:
    """:func:`flycrane.model.direct_kinematics.configuration_from_drone_positions`, compiled;
    ``initial`` (N, 9) is required (the kernel has no rigid-fit start)."""
    a = check_drone_positions(drones)
    start = as_configurations(initial, "initial")
    p = np.ascontiguousarray(start[:, :3])
    r = np.ascontiguousarray(matrix_from_tilt_torsion(start[:, 3:6]))
    residual = np.empty((len(a), 6))
    _newton_rows(np.ascontiguousarray(a), p, r, _model(system), residual, max_iterations)
    return result_from_pose(system, a, p, r, residual)
