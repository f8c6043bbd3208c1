"""The one time law the three drones share along a dense track, and a vertical leg's.

The time law is the fastest one, on the track's grid, under the quasi-static limits
(design.md s.8): every drone's speed <= v_max, the platform's angular rate <= w_max, and
every drone's tangential acceleration (speed change between neighbouring segments) <= a_max,
from rest to rest. Corners of the path change the drones' speed ratios abruptly, which the
acceleration bound turns into slow-downs, as a copter does at waypoints. A vertical leg
(lift-off, set-down) moves at most at its speed, speeding up and braking at a_max.
"""

from __future__ import annotations

import math

import numba
import numpy as np
from numpy.typing import NDArray

from missions.options import MissionOptions


def rotation_angles(rotations: NDArray[np.float64]) -> NDArray[np.float64]:
    """Rotation angle between consecutive orientations (K, 3, 3) -> (K-1,) [rad]."""
    relative = np.einsum("kba,kbc->kac", rotations[:-1], rotations[1:])
    cosine = (np.trace(relative, axis1=1, axis2=2) - 1.0) / 2.0
    return np.arccos(np.clip(cosine, -1.0, 1.0))


def segment_accelerations(
    speeds: NDArray[np.float64], durations: NDArray[np.float64]
) -> NDArray[np.float64]:
    """Tangential accelerations between consecutive constant-speed segments, from rest to
    rest: speeds (K-1, ...) and durations (K-1,) give (K, ...) [m/s^2]."""
    padded = np.concatenate([np.zeros_like(speeds[:1]), speeds, np.zeros_like(speeds[:1])])
    half = np.concatenate([[0.0], durations, [0.0]])
    window = (half[:-1] + half[1:]) / 2
    return np.diff(padded, axis=0) / window.reshape((-1,) + (1,) * (speeds.ndim - 1))


def corner_speeds(drones: NDArray[np.float64], acceleration: float) -> NDArray[np.float64]:
    """Path speed caps (K-1,) that keep every drone's turn at a corner of its track within
    ``acceleration``: turning by theta between two segments changes the velocity by
    2 v sin(theta / 2) over the half-segments around the corner (mean length l), so
    2 g V^2 sin(theta / 2) <= a l, with g the drone's speed per unit path speed."""
    steps = np.diff(drones, axis=0)  # (K-1, 3, 3)
    lengths = np.linalg.norm(steps, axis=-1)  # (K-1, 3)
    ds = np.maximum(lengths.max(axis=1), 1e-12)
    g = lengths / ds[:, None]
    unit = steps / np.maximum(lengths, 1e-12)[..., None]
    cosine = np.clip(np.einsum("kja,kja->kj", unit[:-1], unit[1:]), -1.0, 1.0)
    half_turn = np.sqrt((1.0 - cosine) / 2.0)  # sin(theta / 2)
    mean = (lengths[:-1] + lengths[1:]) / 2
    need = 2.0 * np.maximum(g[:-1], g[1:]) * half_turn  # per drone and corner
    ok = need > 1e-12
    cap = np.where(ok, np.sqrt(acceleration * mean / np.where(ok, need, 1.0)), np.inf)
    corner = cap.min(axis=1)  # (K-2,) the slowest drone's
    caps = np.full(len(ds), np.inf)
    caps[:-1] = np.minimum(caps[:-1], corner)
    caps[1:] = np.minimum(caps[1:], corner)
    return caps


def time_law(
    drones: NDArray[np.float64],
    rotations: NDArray[np.float64],
    options: MissionOptions,
    max_sweeps: int = 200,
    corners: bool = False,
) -> NDArray[np.float64]:
    """Sample times (K,) of the time-optimal law along a dense track (module docstring).

    Each segment between samples is flown at a constant path speed V_k (so drone j at
    g_jk V_k). Speeds start at their velocity limits and are lowered by forward and backward
    sweeps until every drone's speed change between neighbouring segments (and from and to
    rest at the ends) fits the acceleration limit over the two half-segments it spans.
    With ``corners``, the limit also holds for the turns at the track's corners
    (:func:`corner_speeds`): a drone flown on its velocity and acceleration, rather than on
    waypoints an autopilot rounds, must slow down there.
    """
    steps = np.linalg.norm(np.diff(drones, axis=0), axis=-1)  # (K-1, 3) [m]
    ds = np.maximum(steps.max(axis=1), 1e-12)  # path length: the fastest drone's travel
    g = steps / ds[:, None]  # drone speed per unit path speed, (K-1, 3); max is 1
    w = rotation_angles(rotations) / ds
    a = options.max_acceleration
    speed = np.minimum(
        options.max_drone_speed / np.maximum(g.max(axis=1), 1e-12),
        options.max_angular_rate / np.maximum(w, 1e-12),
    )
    if corners:
        speed = np.minimum(speed, corner_speeds(drones, a))
    _lower_speeds(g, ds, speed, a, max_sweeps)
    return np.concatenate([[0.0], np.cumsum(ds / speed)])


@numba.njit(cache=True, nogil=True)
def _largest(a: float, c: NDArray, g: NDArray, k: int, gap: float, length: float) -> float:
    """Largest V with g_jk V - c_j <= a (gap + length / V) / 2 for every drone j: the
    positive root of g V^2 - (c + a gap / 2) V - a length / 2 = 0."""
    best = math.inf
    for j in range(3):
        if g[k, j] > 1e-12:
            b = c[j] + a * gap / 2
            best = min(best, (b + math.sqrt(b * b + 2 * g[k, j] * a * length)) / (2 * g[k, j]))
    return best


@numba.njit(cache=True, nogil=True)
def _lower_speeds(g: NDArray, lengths: NDArray, v: NDArray, a: float, max_sweeps: int) -> None:
    """:func:`time_law`'s sweeps, lowering the segment speeds v (K-1,) in place. Compiled:
    they visit one segment at a time, tens of thousands of root evaluations per track
    (BENCHMARKS.md, "``flycrane plan`` end to end", "Fourth round"), in the same
    floating-point operations in the same order as on Python floats, so the times are
    bit for bit the same."""
    n = len(v)
    c, before = np.zeros(3), np.empty(n)
    for _ in range(max_sweeps):
        for k in range(n):
            before[k] = v[k]
        for k in range(n):  # accelerating into segment k (from rest before the first)
            gap = 0.0
            for j in range(3):
                c[j] = g[k - 1, j] * v[k - 1] if k else 0.0
            if k:
                gap = lengths[k - 1] / v[k - 1]
            v[k] = min(v[k], _largest(a, c, g, k, gap, lengths[k]))
        for k in range(n - 1, -1, -1):  # decelerating out of segment k (to rest after the last)
            gap = 0.0
            for j in range(3):
                c[j] = g[k + 1, j] * v[k + 1] if k < n - 1 else 0.0
            if k < n - 1:
                gap = lengths[k + 1] / v[k + 1]
            v[k] = min(v[k], _largest(a, c, g, k, gap, lengths[k]))
        # Settled once a pair of sweeps moved no speed by more than 1e-9 of itself.
        settled = True
        for k in range(n):
            settled = settled and abs(v[k] - before[k]) <= 1e-9 * abs(before[k])
        if settled:
            return


def vertical_profile(
    height: float, speed: float, acceleration: float, step: float
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Time (M,) and distance travelled (M,) of a rest-to-rest move of ``height`` at most
    ``speed``, speeding up and braking at ``acceleration`` (a trapezoid, or a triangle when
    the move is too short to reach the speed), sampled finely."""
    ramp = speed / acceleration
    if acceleration * ramp * ramp >= height:  # never reaches the speed
        ramp = float(np.sqrt(height / acceleration))
        cruise = 0.0
        speed = acceleration * ramp
    else:
        cruise = (height - acceleration * ramp * ramp) / speed
    total = 2 * ramp + cruise
    t = np.linspace(0.0, total, max(3, int(np.ceil(total / (step / 4))) + 1))
    up = np.minimum(t, ramp)
    down = np.clip(t - ramp - cruise, 0.0, ramp)
    travelled = (
        0.5 * acceleration * up**2
        + speed * np.clip(t - ramp, 0.0, cruise)
        + speed * down
        - 0.5 * acceleration * down**2
    )
    return t, np.minimum(travelled, height)
