"""The local path between configurations: the one geodesic every planner, checker and track uses.

Between configurations a and b the platform position moves on the straight line, the
orientation on the geodesic of SO(3) (spherical linear interpolation of unit quaternions,
constant angular rate about one fixed axis), and each alpha on the short arc of its circle.
That is the shortest path of the state space's metric (its chordal distance is a monotone
function of each part's angle), so a path sampled at a step in that metric is sampled at
that step on the platform and the drones. Interpolating the tilt-and-torsion numbers
themselves is not a geodesic: where the tilt axis reverses, the chart's path rotates much
further than the geodesic.

Quaternion of ``R = Rz(phi) Ry(theta) Rz(sigma - phi)`` (paper eq. 1), from the product of
the three factors' quaternions::

    (w, x, y, z) = (cos(theta/2) cos(sigma/2), sin(theta/2) sin(sigma/2 - phi),
                    sin(theta/2) cos(sigma/2 - phi), cos(theta/2) sin(sigma/2))

so back again ``theta = 2 atan2(|(x, y)|, |(w, z)|)``, ``sigma = 2 atan2(z, w)``,
``phi = sigma/2 - atan2(x, y)``; where the tilt axis is undefined (sin(theta/2) below 1e-12)
phi is 0, the chart's choice in :func:`flycrane.model.kinematics.tilt_torsion_from_matrix`.

The kernels are compiled (numba) because the planner's motion checks call them from
compiled code; :func:`interpolate` and :func:`discretize` are their array front ends.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike, NDArray

from flycrane.kernels import kernel


def wrap_angle(angle: ArrayLike) -> NDArray[np.float64]:
    """Angles wrapped into (-pi, pi]."""
    wrapped = np.remainder(np.asarray(angle, dtype=float) + np.pi, 2.0 * np.pi) - np.pi
    return np.where(wrapped == -np.pi, np.pi, wrapped)


@kernel()
def wrap(angle: float) -> float:
    """One angle wrapped into (-pi, pi]."""
    turns = math.floor((angle + math.pi) / (2.0 * math.pi))
    wrapped = angle - 2.0 * math.pi * turns  # in [-pi, pi) up to rounding
    return math.pi if wrapped <= -math.pi else min(wrapped, math.pi)


@kernel()
def quaternion(phi: float, theta: float, sigma: float) -> tuple[float, float, float, float]:
    """Unit quaternion (w, x, y, z) of the tilt-and-torsion angles (module docstring)."""
    ct, st = math.cos(0.5 * theta), math.sin(0.5 * theta)
    return (
        ct * math.cos(0.5 * sigma),
        st * math.sin(0.5 * sigma - phi),
        st * math.cos(0.5 * sigma - phi),
        ct * math.sin(0.5 * sigma),
    )


@kernel()
def angles_into(w: float, x: float, y: float, z: float, out, offset: int) -> None:
    """Tilt-and-torsion angles of a unit quaternion into out[offset : offset + 3]."""
    tilt_part = math.sqrt(x * x + y * y)
    sigma = 2.0 * math.atan2(z, w)
    # Below 1e-12 of sin(theta/2) the tilt axis is rounding noise (module docstring).
    phi = 0.5 * sigma - math.atan2(x, y) if tilt_part > 1e-12 else 0.0
    out[offset] = wrap(phi)
    out[offset + 1] = 2.0 * math.atan2(tilt_part, math.sqrt(w * w + z * z))
    out[offset + 2] = wrap(sigma)


@kernel()
def rotation_angle_between(a, b) -> float:
    """Angle [rad] of the rotation between the orientations of configurations a and b."""
    aw, ax, ay, az = quaternion(a[3], a[4], a[5])
    bw, bx, by, bz = quaternion(b[3], b[4], b[5])
    dot = abs(aw * bw + ax * bx + ay * by + az * bz)
    return 2.0 * math.acos(min(1.0, dot))


@kernel()
def interpolate_into(a, b, t: float, out) -> None:
    """The configuration at fraction t of the local path a -> b, written into out (9,)."""
    if t == 0.0 or t == 1.0:  # the end points exactly, not their round trip
        end = a if t == 0.0 else b
        for k in range(9):
            out[k] = end[k]
        for k in (3, 5, 6, 7, 8):
            out[k] = wrap(end[k])
        return
    for k in range(3):
        out[k] = a[k] + t * (b[k] - a[k])
    for k in range(6, 9):
        out[k] = wrap(a[k] + t * wrap(b[k] - a[k]))
    aw, ax, ay, az = quaternion(a[3], a[4], a[5])
    bw, bx, by, bz = quaternion(b[3], b[4], b[5])
    dot = aw * bw + ax * bx + ay * by + az * bz
    sign = 1.0
    if dot < 0.0:  # q and -q are one rotation: take the short way round
        sign, dot = -1.0, -dot
    if dot > 1.0 - 1e-12:
        # Rotations within ~1e-6 rad: the chord is the arc to rounding (and sin(omega) ~ 0).
        wa, wb = 1.0 - t, t
    else:
        omega = math.acos(dot)
        wa = math.sin((1.0 - t) * omega) / math.sin(omega)
        wb = math.sin(t * omega) / math.sin(omega)
    tw, tx = wa * aw + wb * sign * bw, wa * ax + wb * sign * bx
    ty, tz = wa * ay + wb * sign * by, wa * az + wb * sign * bz
    norm = math.sqrt(tw * tw + tx * tx + ty * ty + tz * tz)
    angles_into(tw / norm, tx / norm, ty / norm, tz / norm, out, 3)


@kernel()
def _interpolate_rows(a, b, t, out) -> None:
    for row in range(len(t)):
        interpolate_into(a[row], b[row], t[row], out[row])


@kernel()
def geodesic_length(a, b, rotation_weight: float, alpha_weight: float) -> float:
    """Length of the local path a -> b: sqrt(|dp|^2 + (rho_R w)^2 + sum (rho_a d_alpha)^2).

    Never shorter than the chordal distance of the same two configurations
    (:class:`~flycrane.planning.state_space.ConfigurationSpace`), so steps of the local path
    at most ``length / n`` long are at most that long in the chordal metric too.
    """
    total = 0.0
    for k in range(3):
        total += (b[k] - a[k]) ** 2
    total += (rotation_weight * rotation_angle_between(a, b)) ** 2
    for k in range(6, 9):
        total += (alpha_weight * wrap(b[k] - a[k])) ** 2
    return math.sqrt(total)


@kernel()
def geodesic_lengths(a, b, rotation_weight: float, alpha_weight: float, out) -> None:
    for row in range(len(out)):
        out[row] = geodesic_length(a[row], b[row], rotation_weight, alpha_weight)


@kernel()
def segment_count(a, b, resolution: float, rotation_weight: float, alpha_weight: float) -> int:
    """Pieces of the local path a -> b so that none is longer than ``resolution`` (>= 1)."""
    return max(1, math.ceil(geodesic_length(a, b, rotation_weight, alpha_weight) / resolution))


@kernel()
def discretize_into(a, b, pieces: int, out) -> None:
    """pieces + 1 configurations evenly spaced along a -> b, ends included, into out."""
    for k in range(pieces + 1):
        interpolate_into(a, b, k / pieces, out[k])


def interpolate(q_from: ArrayLike, q_to: ArrayLike, t: ArrayLike) -> NDArray[np.float64]:
    """Configurations at fractions t of the local path from q_from to q_to.

    Parameters
    ----------
    q_from, q_to : array-like, shape (9,) or (N, 9)
    t : array-like, shape (K,) or scalar
        Fractions in [0, 1]; t = 0 gives q_from and t = 1 gives q_to (angles wrapped).

    Returns
    -------
    q : ndarray, shape (K, 9) for single configurations, or (N, 9) row by row with (N,) t.
    """
    a = np.atleast_2d(np.asarray(q_from, dtype=float))
    b = np.atleast_2d(np.asarray(q_to, dtype=float))
    t = np.atleast_1d(np.asarray(t, dtype=float))
    rows = max(len(a), len(b), len(t))
    a, b = np.broadcast_to(a, (rows, 9)), np.broadcast_to(b, (rows, 9))
    t = np.broadcast_to(t, (rows,))
    out = np.empty((rows, 9))
    _interpolate_rows(
        np.ascontiguousarray(a), np.ascontiguousarray(b), np.ascontiguousarray(t), out
    )
    return out
