"""ArduCopter's spline legs (NAV_SPLINE_WAYPOINT), as AC_WPNav and AP_Math SplineCurve fly
them in Copter 4.5, for a chain of spline waypoints flown without stopping.

**Geometry.** Each leg from P0 to P1 is a cubic Hermite curve in a parameter u in [0, 1],
``P(u) = P0 + V0 u + (3 (P1 - P0) - 2 V0 - V1) u^2 + (2 (P0 - P1) + V0 + V1) u^3``. Its end
tangents are set when the leg starts (``ModeAuto::do_spline_wp``,
``AC_WPNav::set_spline_destination`` and ``set_spline_destination_next``): the origin
tangent is the previous spline leg's destination tangent (as given, before it is scaled)
when the vehicle flies on through the waypoint, zero when it starts from rest (after any
other nav item, a stop, or a jump); the destination tangent is the vector from the leg's
origin to the next nav item if that is a spline waypoint, else from the leg's destination
to it. So between two spline legs the tangent is the vector from the previous waypoint to
the next one (``P(k+1) - P(k-1)``, twice the Catmull-Rom tangent), and a leg ending at a
stop (a hold time at the waypoint, or a next item at the same place, as the final hold)
has a zero destination tangent. If ``|V0| + |V1|`` exceeds four times the chord, both are
scaled down to that (SplineCurve's SPLINE_FACTOR).

**Speed**, every step of ``dt`` (400 Hz on the vehicle): the largest speed along the curve's
tangent within the horizontal, climb and descent limits (``kinematic_limit``), lowered where
the curve bends so that the lateral acceleration stays within half the kinematic
acceleration limit, and lowered near the leg's end so that the vehicle can brake at half the
tangential acceleration limit to the next leg's starting speed. The speed moves towards that
limit by at most half the tangential acceleration limit per second. The parameter advances
by the distance flown at the previous step's speed. Limits are read at every step, so a
DO_CHANGE_SPEED acts at once (at the leg's start, where the mission runs its DO items).

**The leg's clock** (``AC_WPNav::advance_wp_target_along_track``) runs slower while the
vehicle lags its target: its rate is ``0.05 + (v_track - P e) / |v_target|``, clamped to
[0, 1] and low-pass filtered with time constant ``0.01 WPNAV_ACCEL / WPNAV_JERK``, where
``e`` is how far the vehicle is behind along the track and ``v_track`` its speed along it.
So the vehicle's own response matters: :class:`Tracking` models it as the position
controller's gains (horizontal and vertical apart, as AC_PosControl has them) and a
first-order lag on the acceleration the airframe reaches. On a spline leg AC_WPNav hands the
position controller the target's position and velocity but **no acceleration** (its
``target_accel`` stays zero: read in AC_WPNav 4.5 and seen in the SITL flights' PSC logs,
BENCHMARKS.md "Moved from code comments"), so the vehicle feels a speed change only
through its velocity error and overshoots a braking target: that keeps it ahead of the
target at the end of a slow stop, where a model with feed-forward would have it catch up
and slow the clock (``docs/missions.md``, the mock's calibration).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numba
import numpy as np
from numpy.typing import NDArray

#: SplineCurve's SPLINE_FACTOR, TANGENTIAL_ACCEL_SCALER and LATERAL_ACCEL_SCALER.
SPLINE_FACTOR = 4.0
TANGENTIAL_ACCEL_SCALER = 0.5
LATERAL_ACCEL_SCALER = 0.5
#: AC_WPNav's loop period [s] (the vehicle's 400 Hz main loop).
WPNAV_DT = 0.0025
#: Longest leg :func:`fly_leg` flies by default [s]; a longer one stops unfinished.
MAX_LEG_TIME = 600.0


def kinematic_limit(
    direction: NDArray[np.float64], horizontal: float, up: float, down: float
) -> float:
    """The largest magnitude along ``direction`` (any length, ENU) whose horizontal part is
    within ``horizontal`` and whose vertical part within ``up`` or ``down`` (AP_Math)."""
    norm = float(np.linalg.norm(direction))
    if norm == 0.0:
        return 0.0
    c = math.hypot(float(direction[0]), float(direction[1])) / norm
    s = float(direction[2]) / norm
    limits = [horizontal / c] if c > 1e-9 else []
    if s > 1e-9:
        limits.append(up / s)
    elif s < -1e-9:
        limits.append(down / -s)
    return min(limits) if limits else 0.0


@dataclass(frozen=True)
class SpeedLimits:
    """Horizontal, climb and descent speed limits [m/s] (WPNAV_SPEED*, DO_CHANGE_SPEED)."""

    horizontal: float
    up: float
    down: float


@dataclass(frozen=True)
class AccelLimits:
    """Horizontal and vertical acceleration limits [m/s^2] (WPNAV_ACCEL, WPNAV_ACCEL_Z)."""

    horizontal: float
    vertical: float


@dataclass(frozen=True)
class HermiteLeg:
    """One spline leg: ``P(u) = c0 + c1 u + c2 u^2 + c3 u^3`` (ENU metres)."""

    coefficients: NDArray[np.float64]  #: (4, 3)

    @classmethod
    def between(
        cls,
        origin: NDArray[np.float64],
        destination: NDArray[np.float64],
        origin_tangent: NDArray[np.float64],
        destination_tangent: NDArray[np.float64],
    ) -> HermiteLeg:
        """The leg with ArduPilot's tangent scaling (module docstring)."""
        p0, p1 = np.asarray(origin, float), np.asarray(destination, float)
        v0, v1 = np.asarray(origin_tangent, float), np.asarray(destination_tangent, float)
        total = float(np.linalg.norm(v0) + np.linalg.norm(v1))
        reach = float(np.linalg.norm(p1 - p0)) * SPLINE_FACTOR
        if total > reach:
            v0, v1 = v0 * reach / total, v1 * reach / total
        return cls(np.stack([p0, v0, 3 * (p1 - p0) - 2 * v0 - v1, 2 * (p0 - p1) + v0 + v1]))

    @property
    def origin(self) -> NDArray[np.float64]:
        return self.coefficients[0]

    @property
    def destination(self) -> NDArray[np.float64]:
        return self.coefficients.sum(axis=0)

    def position(self, u: NDArray[np.float64] | float) -> NDArray[np.float64]:
        """P(u), shape (..., 3)."""
        u = np.asarray(u, dtype=float)[..., None]
        c = self.coefficients
        return c[0] + u * (c[1] + u * (c[2] + u * c[3]))

    def derivatives(
        self, u: float
    ) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
        """P'(u), P''(u), P'''(u)."""
        c = self.coefficients
        return c[1] + 2 * c[2] * u + 3 * c[3] * u * u, 2 * c[2] + 6 * c[3] * u, 6 * c[3]


def tangents(
    points: NDArray[np.float64], start_at_rest: bool = True, stop_at_end: bool = True
) -> NDArray[np.float64]:
    """AC_WPNav's tangent at every waypoint of a chain of spline legs (K, 3): the
    previous-to-next vector inside, zero at a start from rest and at a final stop."""
    points = np.asarray(points, dtype=float)
    result = np.zeros_like(points)
    result[1:-1] = points[2:] - points[:-2]
    if not start_at_rest:
        result[0] = points[1] - points[0]
    if not stop_at_end:
        result[-1] = points[-1] - points[-2]
    return result


def legs_through(points: NDArray[np.float64]) -> list[HermiteLeg]:
    """The spline legs of a chain from rest at ``points[0]`` to a stop at ``points[-1]``."""
    t = tangents(points)
    return [
        HermiteLeg.between(points[k], points[k + 1], t[k], t[k + 1]) for k in range(len(points) - 1)
    ]


@numba.njit(cache=True, nogil=True)
def _kinematic(dx, dy, dz, horizontal, up, down):
    """kinematic_limit of a direction given by its components (any length)."""
    norm = math.sqrt(dx * dx + dy * dy + dz * dz)
    if norm == 0.0:
        return 0.0
    c = math.sqrt(dx * dx + dy * dy) / norm
    s = dz / norm
    best = math.inf
    if c > 1e-9:
        best = horizontal / c
    if s > 1e-9:
        best = min(best, up / s)
    elif s < -1e-9:
        best = min(best, down / -s)
    return 0.0 if best == math.inf else best


@numba.njit(cache=True, nogil=True)
def _limits_at(c, u, vxy, vup, vdn, axy, az):
    """SplineCurve::calc_dt_speed_max at u, without the braking term: the speed limit, the
    tangential acceleration limit, and the norms of the curve's first three derivatives.

    Scalars only: it runs at every 2.5 ms step of every leg the speed solver tries, and
    three small arrays per step cost more than the arithmetic."""
    vx = c[1, 0] + 2.0 * c[2, 0] * u + 3.0 * c[3, 0] * u * u
    vy = c[1, 1] + 2.0 * c[2, 1] * u + 3.0 * c[3, 1] * u * u
    vz = c[1, 2] + 2.0 * c[2, 2] * u + 3.0 * c[3, 2] * u * u
    acc_x = 2.0 * c[2, 0] + 6.0 * c[3, 0] * u
    acc_y = 2.0 * c[2, 1] + 6.0 * c[3, 1] * u
    acc_z = 2.0 * c[2, 2] + 6.0 * c[3, 2] * u
    jerk_x, jerk_y, jerk_z = 6.0 * c[3, 0], 6.0 * c[3, 1], 6.0 * c[3, 2]
    length = math.sqrt(vx * vx + vy * vy + vz * vz)
    acc_norm = math.sqrt(acc_x * acc_x + acc_y * acc_y + acc_z * acc_z)
    jerk_norm = math.sqrt(jerk_x * jerk_x + jerk_y * jerk_y + jerk_z * jerk_z)
    if length > 0.0:
        ux, uy, uz = vx / length, vy / length, vz / length
    elif acc_norm > 0.0:
        ux, uy, uz = acc_x / acc_norm, acc_y / acc_norm, acc_z / acc_norm
    else:
        ux, uy, uz = jerk_x / jerk_norm, jerk_y / jerk_norm, jerk_z / jerk_norm
    along = acc_x * ux + acc_y * uy + acc_z * uz
    nx, ny, nz = acc_x - ux * along, acc_y - uy * along, acc_z - uz * along
    normal_length = math.sqrt(nx * nx + ny * ny + nz * nz)
    tangential = _kinematic(ux, uy, uz, vxy, vup, vdn)
    lateral = LATERAL_ACCEL_SCALER * _kinematic(nx, ny, nz, axy, az, az)
    limit = tangential
    if lateral > 0.0 and normal_length > 0.0 and length > 0.0:
        if normal_length / lateral > (length / tangential) ** 2:
            limit = length / math.sqrt(normal_length / lateral)
    tangential_accel = TANGENTIAL_ACCEL_SCALER * _kinematic(ux, uy, uz, axy, az, az)
    return limit, tangential_accel, length, acc_norm, jerk_norm


@numba.njit(cache=True, nogil=True)
def _fly(c, vxy, vup, vdn, axy, az, entry, exit_max, dt, max_steps, state, lag):
    """Step the target along a leg (module docstring), with the vehicle following it.

    ``state`` is the vehicle's position, velocity, acceleration and the leg clock's scaler
    (10 numbers), updated in place; ``lag`` the tracking model (:meth:`Tracking.array`:
    horizontal position and velocity gains and acceleration time constant, the scaler's
    filter time constant, the same three vertically; tau <= 0: a vehicle exactly on its
    target, the scaler always 1). Returns u, the target speed and the vehicle position after
    every step.

    Arrays are copied element by element: a slice assignment makes numba compile its
    shape-mismatch error message (string formatting), seconds of a fresh install's first run.
    """
    kp, tau, tc = lag[0], lag[2], lag[3]
    u_out = np.empty(max_steps + 1)
    v_out = np.empty(max_steps + 1)
    x_out = np.empty((max_steps + 1, 3))
    dest = c[0] + c[1] + c[2] + c[3]
    target = np.empty(3)
    unit = np.zeros(3)
    u, v = 0.0, entry
    for i in range(3):
        target[i] = c[0, i]
    if tau <= 0.0:
        for i in range(3):
            state[i] = target[i]
    u_out[0], v_out[0] = u, v
    for i in range(3):
        x_out[0, i] = state[i]
    n = 0
    while u < 1.0 and n < max_steps:
        limit, along, length, acc_norm, jerk_norm = _limits_at(c, u, vxy, vup, vdn, axy, az)
        for i in range(3):
            unit[i] = c[1, i] + 2.0 * c[2, i] * u + 3.0 * c[3, i] * u * u
        if length > 0.0:
            for i in range(3):
                unit[i] /= length
        scale = 1.0
        if tau > 0.0:
            # AC_WPNav's leg clock: slowed while the vehicle lags its target (+5 % buffer)
            instant = 1.0
            if v > 0.0:
                error = 0.0
                track = 0.0
                for i in range(3):
                    error += (target[i] - state[i]) * unit[i]
                    track += state[3 + i] * unit[i]
                instant = min(max(0.05 + (track - kp * error) / v, 0.0), 1.0)
            state[9] += (instant - state[9]) * dt / tc
            scale = state[9]
        step_dt = scale * dt
        d2 = 0.0
        for i in range(3):
            d2 += (dest[i] - target[i]) ** 2
        limit = min(limit, math.sqrt(2.0 * along * math.sqrt(d2) + exit_max * exit_max))
        step = v * step_dt
        if length > 0.0:
            du = step / length
        elif acc_norm > 0.0:  # a cusp: ArduPilot steps along the acceleration
            du = math.sqrt(2.0 * step / acc_norm)
        else:
            du = (6.0 * step / jerk_norm) ** (1.0 / 3.0)
        v = min(max(limit, v - along * step_dt), v + along * step_dt)
        u = min(u + du, 1.0)
        for i in range(3):
            target[i] = c[0, i] + u * (c[1, i] + u * (c[2, i] + u * c[3, i]))
        if tau > 0.0:
            # the position controller: velocity command from the position error, then the
            # acceleration command (no feed-forward, module docstring), which the airframe
            # reaches with a first-order lag; horizontal axes, then the vertical one
            for i in range(3):
                gains = 0 if i < 2 else 4
                command = unit[i] * v + lag[gains] * (target[i] - state[i])
                wanted = lag[gains + 1] * (command - state[3 + i])
                if lag[gains + 2] > 0.0:
                    state[6 + i] += (wanted - state[6 + i]) * dt / lag[gains + 2]
                else:
                    state[6 + i] = wanted
                state[3 + i] += state[6 + i] * dt
                state[i] += state[3 + i] * dt
        else:
            for i in range(3):
                state[i] = target[i]
        n += 1
        u_out[n], v_out[n] = u, v
        for i in range(3):
            x_out[n, i] = state[i]
    return u_out[: n + 1], v_out[: n + 1], x_out[: n + 1]


def entry_speed_limit(leg: HermiteLeg, speed: SpeedLimits, accel: AccelLimits) -> float:
    """The largest speed at the leg's start (SplineCurve's origin speed max) [m/s]; 0 for a
    zero-length leg, which SplineCurve treats as reached."""
    if not np.any(leg.destination - leg.origin):
        return 0.0
    limit = _limits_at(
        leg.coefficients, 0.0, speed.horizontal, speed.up, speed.down,
        accel.horizontal, accel.vertical,
    )[0]  # fmt: skip
    return float(limit)


@dataclass(frozen=True)
class Tracking:
    """How a vehicle follows its target, and how its leg clock reacts (module docstring).

    ``position_p`` and ``velocity_p`` are the position controller's horizontal gains
    (PSC_POSXY_P, PSC_VELXY_P), ``position_p_z`` and ``velocity_p_z`` its vertical ones
    (PSC_POSZ_P, PSC_VELZ_P); ``accel_lag`` and ``accel_lag_z`` the time constants [s] with
    which the airframe reaches the horizontal acceleration it is asked for (its attitude
    response) and the vertical one (its thrust); ``clock_tc`` the leg clock's filter, 0.01
    WPNAV_ACCEL [cm/s^2] / WPNAV_JERK [m/s^3] [s]; the clock compares the along-track error
    with ``position_p`` (AC_WPNav uses the horizontal gain). ``accel_lag = 0`` is a vehicle
    exactly on its target; ``accel_lag_z = 0`` alone, one whose thrust follows at once. The
    lags are calibrated on SITL flights
    (:class:`~missions.autopilots.ardupilot.ArduCopterSettings`).
    """

    position_p: float = 1.0
    velocity_p: float = 2.0
    accel_lag: float = 0.0
    clock_tc: float = 2.0
    position_p_z: float = 1.0
    velocity_p_z: float = 5.0
    accel_lag_z: float = 0.0

    def array(self) -> NDArray[np.float64]:
        return np.array(
            [
                self.position_p, self.velocity_p, self.accel_lag, self.clock_tc,
                self.position_p_z, self.velocity_p_z, self.accel_lag_z,
            ]
        )  # fmt: skip


def vehicle_state(position: NDArray[np.float64]) -> NDArray[np.float64]:
    """A vehicle at rest at ``position`` with an unslowed leg clock (see :func:`fly_leg`)."""
    return np.concatenate([np.asarray(position, dtype=float), np.zeros(6), [1.0]])


@dataclass(frozen=True)
class LegFlight:
    """A leg as flown: the target and the vehicle every step from the leg's start."""

    time: NDArray[np.float64]  #: (N,) [s] from the leg's start
    u: NDArray[np.float64]  #: (N,) curve parameter of the target
    speed: NDArray[np.float64]  #: (N,) target speed [m/s]
    vehicle: NDArray[np.float64]  #: (N, 3) vehicle position [m]
    state: NDArray[np.float64]  #: the vehicle's state at the end (:func:`vehicle_state`)

    @property
    def duration(self) -> float:
        return float(self.time[-1])

    @property
    def exit_speed(self) -> float:
        return float(self.speed[-1])


def fly_leg(
    leg: HermiteLeg,
    speed: SpeedLimits,
    accel: AccelLimits,
    entry_speed: float,
    exit_speed_max: float,
    tracking: Tracking | None = None,
    state: NDArray[np.float64] | None = None,
    dt: float = WPNAV_DT,
    max_time: float = MAX_LEG_TIME,
) -> LegFlight:
    """The target's motion along ``leg`` from ``entry_speed`` until u reaches 1, braking
    towards ``exit_speed_max`` (the next leg's entry limit, 0 for a stop), and the vehicle
    following it from ``state`` (default: at rest on the leg's origin)."""
    tracking = tracking or Tracking()
    state = vehicle_state(leg.origin) if state is None else np.array(state, dtype=float)
    if not np.any(leg.destination - leg.origin):  # SplineCurve: a zero-length leg is reached
        return LegFlight(np.zeros(1), np.ones(1), np.zeros(1), state[None, :3], state)
    u, v, x = _fly(
        leg.coefficients, speed.horizontal, speed.up, speed.down, accel.horizontal,
        accel.vertical, float(entry_speed), float(exit_speed_max), dt, int(max_time / dt),
        state, tracking.array(),
    )  # fmt: skip
    return LegFlight(np.linspace(0.0, (len(u) - 1) * dt, len(u)), u, v, x, state)
