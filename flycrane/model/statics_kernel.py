"""Compiled (numba) statics and cost: the planner's hot path.

One loop over configurations computes, per row, exactly the formulas of
:mod:`flycrane.model.statics` and :mod:`flycrane.model.cost` (which remain the readable
reference and are what the tests compare this kernel against): rotation (eq. 1), drone and
platform points (eq. 2), screw Jacobian, f0 = J^-1 w0 (eq. 3), v_ii as row norms of J^-1 L with
L L^T = E^-1 (eq. 4-6), m_k as the largest corner thrust (eq. 7) and the cost (eq. 8).
J is factorized once per row by Gaussian elimination with partial pivoting and the same
Hadamard-ratio singularity test as the reference.

Why compiled: numpy spends ~1 us per call on every small array operation, which puts one
configuration at hundreds of microseconds; the planner evaluates single configurations in
its inner loop (BENCHMARKS.md, "Cost evaluations per second").
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike, NDArray

from flycrane.kernels import kernel
from flycrane.model.cable_system import CABLE_DRONE, CableSystem
from flycrane.model.cost import CostForm
from flycrane.model.kinematics import as_configurations
from flycrane.model.pose_kernel import drone_offsets_into, rotation_into
from flycrane.model.statics import SINGULARITY_THRESHOLD
from flycrane.model.system_spec import DRONE_CABLES

_CABLE_DRONE = np.array(CABLE_DRONE, dtype=np.int64)
_DRONE_CABLES = np.array(DRONE_CABLES, dtype=np.int64)


@kernel(inline="always")
def eliminate(a, b) -> float:
    """Gaussian elimination with partial pivoting of a x = b in place: a (6, 6) becomes
    upper triangular, b (6, k) follows; returns det(a) from the pivots (0 at the first zero
    pivot, where it stops). The statics' and the direct kinematics' 6 x 6 systems; the size
    is a constant, not a.shape[0], so the compiler knows the loops' bounds."""
    n, k = 6, b.shape[1]
    det = 1.0
    for col in range(n):
        pivot = col
        for r in range(col + 1, n):
            if abs(a[r, col]) > abs(a[pivot, col]):
                pivot = r
        if pivot != col:
            det = -det
            for c in range(n):
                a[col, c], a[pivot, c] = a[pivot, c], a[col, c]
            for c in range(k):
                b[col, c], b[pivot, c] = b[pivot, c], b[col, c]
        det *= a[col, col]
        if a[col, col] == 0.0:
            return 0.0
        for r in range(col + 1, n):
            factor = a[r, col] / a[col, col]
            for c in range(col, n):
                a[r, c] -= factor * a[col, c]
            for c in range(k):
                b[r, c] -= factor * b[col, c]
    return det


@kernel(inline="always")
def back_substitute(a, b) -> None:
    """x of the triangular system :func:`eliminate` left, written over b (6, k)."""
    n, k = 6, b.shape[1]
    for r in range(n - 1, -1, -1):
        for c in range(k):
            acc = b[r, c]
            for j in range(r + 1, n):
                acc -= a[r, j] * b[j, c]
            b[r, c] = acc / a[r, r]


@kernel(inline="always")
def statics_row(q, model, f0_out, v_out, m_out, work) -> float:
    """Statics of one configuration q (9,): f0 (6,), v (6,), m (3,) into the outputs; returns
    the cost (+inf where infeasible or singular; then the outputs are +inf). ``model`` is
    :func:`statics_model`'s tuple, ``work`` :func:`statics_workspace`, so that a row
    allocates nothing. The pose it leaves in ``work`` (R in work[0], the drones in the
    platform frame in work[5], :mod:`flycrane.model.pose_kernel`) is q's: a state check's
    collision test reuses it."""
    (
        points,
        foot,
        radius,
        outward,
        up,
        com,
        drone_weight,
        thrust_max,
        f_lo,
        f_hi,
        lsqrt,
        scalars,
        cable_drone,
        drone_cables,
    ) = model
    platform_weight, threshold, normalized = scalars[0], scalars[1], scalars[2] > 0.0
    rot, drones, unit, jac, rhs, offsets = work
    rotation_into(q, rot)
    drone_offsets_into(q, foot, radius, outward, up, offsets)
    # Drones relative to P in world axes: R a'_k, a'_k = F_k + h_k (cos a n_k + sin a z_k).
    for k in range(3):
        for a in range(3):
            acc = 0.0
            for b in range(3):
                acc += rot[a, b] * offsets[k, b]
            drones[k, a] = acc
    # Jacobian columns [u_i ; (b_i - p) x u_i] and their norms for the singularity test.
    column_norms = 1.0
    for i in range(6):
        arm0 = rot[0, 0] * points[i, 0] + rot[0, 1] * points[i, 1] + rot[0, 2] * points[i, 2]
        arm1 = rot[1, 0] * points[i, 0] + rot[1, 1] * points[i, 1] + rot[1, 2] * points[i, 2]
        arm2 = rot[2, 0] * points[i, 0] + rot[2, 1] * points[i, 1] + rot[2, 2] * points[i, 2]
        k = cable_drone[i]
        d0, d1, d2 = drones[k, 0] - arm0, drones[k, 1] - arm1, drones[k, 2] - arm2
        length = math.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
        u0, u1, u2 = d0 / length, d1 / length, d2 / length
        unit[i, 0], unit[i, 1], unit[i, 2] = u0, u1, u2
        jac[0, i], jac[1, i], jac[2, i] = u0, u1, u2
        jac[3, i] = arm1 * u2 - arm2 * u1
        jac[4, i] = arm2 * u0 - arm0 * u2
        jac[5, i] = arm0 * u1 - arm1 * u0
        column_norms *= math.sqrt(1.0 + jac[3, i] ** 2 + jac[4, i] ** 2 + jac[5, i] ** 2)
    # Right-hand sides: w0 = [0, 0, m g ; c x (0, 0, m g)] with c = R c', then L.
    c0 = rot[0, 0] * com[0] + rot[0, 1] * com[1] + rot[0, 2] * com[2]
    c1 = rot[1, 0] * com[0] + rot[1, 1] * com[1] + rot[1, 2] * com[2]
    rhs[0, 0], rhs[1, 0], rhs[2, 0] = 0.0, 0.0, platform_weight
    rhs[3, 0], rhs[4, 0], rhs[5, 0] = c1 * platform_weight, -c0 * platform_weight, 0.0
    for a in range(6):
        for b in range(6):
            rhs[a, b + 1] = lsqrt[a, b]
    det = eliminate(jac, rhs)
    if abs(det) <= threshold * column_norms:
        for i in range(6):
            f0_out[i] = math.inf
            v_out[i] = math.inf
        for k in range(3):
            m_out[k] = math.inf
        return math.inf
    back_substitute(jac, rhs)
    log_cost = 0.0
    feasible = True
    for i in range(6):
        f0_out[i] = rhs[i, 0]
        acc = 0.0
        for b in range(1, 7):
            acc += rhs[i, b] * rhs[i, b]
        v = math.sqrt(acc)
        v_out[i] = v
        span = (f_hi[i] - f_lo[i]) if normalized else 1.0
        slack = (rhs[i, 0] - v - f_lo[i]) / span
        overload = (f_hi[i] - rhs[i, 0] - v) / span
        if slack <= 0.0 or overload <= 0.0:
            feasible = False
        else:
            log_cost -= math.log(slack) + math.log(overload)
    # Thrust bound: |T| is convex in the two tensions, so check the four corners.
    for k in range(3):
        i, j = drone_cables[k, 0], drone_cables[k, 1]
        best = 0.0
        for si in (-1.0, 1.0):
            ti = f0_out[i] + si * v_out[i]
            for sj in (-1.0, 1.0):
                tj = f0_out[j] + sj * v_out[j]
                # T = -(M g_vec + t_i w_i + t_j w_j), w = -u: T = t_i u_i + t_j u_j + M g z
                t0 = ti * unit[i, 0] + tj * unit[j, 0]
                t1 = ti * unit[i, 1] + tj * unit[j, 1]
                t2 = ti * unit[i, 2] + tj * unit[j, 2] + drone_weight[k]
                best = max(best, math.sqrt(t0 * t0 + t1 * t1 + t2 * t2))
        m_out[k] = best
        margin = (thrust_max[k] - best) / (thrust_max[k] if normalized else 1.0)
        if margin <= 0.0:
            feasible = False
        else:
            log_cost -= math.log(margin)
    # exp overflows to +inf for costs beyond ~1e308, which is what +inf means here.
    return math.exp(log_cost) if feasible and log_cost < 709.0 else math.inf


@kernel()
def _statics_rows(q, model, f0_out, v_out, m_out, cost_out, work) -> None:
    for row in range(q.shape[0]):
        cost_out[row] = statics_row(q[row], model, f0_out[row], v_out[row], m_out[row], work)


def statics_workspace() -> tuple:
    """Scratch of :func:`statics_row`: R, the drones, the cables' unit vectors, J, the
    right-hand sides and the drones in the platform frame."""
    return tuple(np.empty(shape) for shape in ((3, 3), (3, 3), (6, 3), (6, 6), (6, 7), (3, 3)))


def statics_model(system: CableSystem, form: CostForm = CostForm.NORMALIZED) -> tuple:
    """The system's constants as the tuple :func:`statics_row` takes (arrays only, so one
    compiled signature serves every system)."""
    normalized = CostForm(form) is CostForm.NORMALIZED
    return (
        np.ascontiguousarray(system.platform_points),
        np.ascontiguousarray(system.drone_foot),
        np.ascontiguousarray(system.drone_radius),
        np.ascontiguousarray(system.drone_outward),
        np.ascontiguousarray(system.drone_up),
        np.ascontiguousarray(system.com_offset),
        np.ascontiguousarray(system.drone_masses * system.gravity),
        np.ascontiguousarray(system.max_thrusts),
        np.ascontiguousarray(system.tension_min),
        np.ascontiguousarray(system.tension_max),
        np.ascontiguousarray(system.perturbation_sqrt),
        np.array([system.platform_mass * system.gravity, SINGULARITY_THRESHOLD, float(normalized)]),
        _CABLE_DRONE,
        _DRONE_CABLES,
    )


def compiled_statics(
    system: CableSystem, q: ArrayLike, form: CostForm = CostForm.NORMALIZED
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """(f0 (N, 6), v (N, 6), m (N, 3), cost (N,)); singular rows are +inf throughout."""
    q = as_configurations(q)
    model, n = statics_model(system, form), len(q)
    f0, v, m, cost = np.empty((n, 6)), np.empty((n, 6)), np.empty((n, 3)), np.empty(n)
    _statics_rows(q, model, f0, v, m, cost, statics_workspace())
    return f0, v, m, cost


def statics_margins(
    system: CableSystem, q: ArrayLike
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """(cost (N,), margins (N, 3) [N]) of configurations: each one's least slack margin
    (t_lo - t_min), overload headroom (t_max - t_hi) and thrust margin (h_k - m_k) over its
    cables and drones (design.md s.5), the least margins of the paper's Fig. 6."""
    f0, v, m, cost = compiled_statics(system, q)
    slack = (f0 - v - system.tension_min).min(axis=1)
    headroom = (system.tension_max - f0 - v).min(axis=1)
    return cost, np.stack([slack, headroom, (system.max_thrusts - m).min(axis=1)], axis=1)


def configuration_cost(
    system: CableSystem, q: ArrayLike, form: CostForm = CostForm.NORMALIZED
) -> NDArray[np.float64]:
    """Cost c(q) of configurations, shape (N,), +inf where infeasible or singular: the
    planner's hot path; :func:`~flycrane.model.cost.cost_from_report` over
    :func:`~flycrane.model.statics.evaluate_statics` is the numpy reference it is tested
    against."""
    return compiled_statics(system, q, form)[3]
