"""ArduCopter's jerk-limited straight leg from rest to rest (AP_Math SCurve, Copter 4.5).

A leg of length L is flown along its chord with a velocity profile of three phases:
acceleration, constant speed V, deceleration (the mirror image of the acceleration). The
acceleration phase has seven segments: jerk rising to ``Jm`` over ``tj`` as a raised
cosine (the "snap" shaping), constant jerk for ``t2``, jerk falling over ``tj``, constant
acceleration ``Ap = Jm (tj + t2)`` for ``t4``, and the same three mirrored. Its duration
and the speed it gains are::

    T_acc = 4 tj + 2 t2 + t4,        V = Ap (2 tj + t2 + t4)

How ArduPilot chooses them (SCurve::calculate_path, from the source and checked on the
4.5.7 SITL binary, see ``docs/missions.md``):

- ``tj = Jm pi / (2 S)`` with the snap ``S = J pi / (4 max(ATC_INPUT_TC, 0.1))``, so tj is
  twice ATC_INPUT_TC (0.3 s by default) whatever the jerk ``J`` (WPNAV_JERK);
- if V can be reached at the acceleration limit A: ``t2 = A/J - tj``,
  ``t4 = V/A - (tj + A/J)``; else (low speeds: V < A tj + A^2/J) ``t4 = 0`` and the peak
  acceleration ``Ap = J (-tj + sqrt(tj^2 + 4 V / J)) / 2``, ``t2 = Ap/J - tj``;
- when ``min(A, V / (2 tj), (L/2) / (4 tj^2)) < J tj`` (very slow or very short legs)
  the jerk pulse is shortened: ``tj = min(tj, (L pi / (16 S))^(1/4), (V pi / (4 S))^(1/3),
  sqrt(A pi / (2 S)))``, ``Jm = 2 S tj / pi`` and ``A = Jm tj``;
- a leg too short to reach V (``L < V T_acc``) peaks at the speed whose acceleration and
  deceleration cover L exactly (found here by bisection on the peak speed; ArduPilot
  solves the same profile family in closed form).

Speeds and accelerations along a 3-D chord are the largest whose horizontal and vertical
parts keep within the horizontal and the climb or descent limits (AP_Math
``kinematic_limit``): :func:`chord_limit`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

#: Bisection steps for a short leg's peak speed (relative precision 2^-60).
BISECTION_STEPS = 60


def chord_limit(direction: NDArray[np.float64], horizontal: float, up: float, down: float) -> float:
    """The largest magnitude along unit ``direction`` (ENU) whose horizontal part is at
    most ``horizontal`` and whose vertical part at most ``up`` (climbing) or ``down``."""
    c = math.hypot(float(direction[0]), float(direction[1]))
    s = float(direction[2])
    limits = [horizontal / c] if c > 1e-12 else []
    if s > 1e-12:
        limits.append(up / s)
    elif s < -1e-12:
        limits.append(down / -s)
    return min(limits) if limits else math.inf


@dataclass(frozen=True)
class JerkLimits:
    """The jerk, snap and acceleration a leg is built with."""

    jerk: float  #: J [m/s^3] (WPNAV_JERK)
    snap: float  #: S [m/s^4]
    accel: float  #: A along the chord [m/s^2]

    @classmethod
    def of(cls, jerk: float, input_tc: float, accel: float) -> JerkLimits:
        """From WPNAV_JERK, ATC_INPUT_TC and the chord's acceleration limit."""
        return cls(jerk, jerk * math.pi / (4.0 * max(input_tc, 0.1)), accel)


@dataclass(frozen=True)
class AccelPhase:
    """One acceleration phase: jerk pulse ``tj``, peak jerk ``jm``, segments ``t2``, ``t4``."""

    tj: float
    jm: float
    t2: float
    t4: float

    @property
    def peak_accel(self) -> float:
        return self.jm * (self.tj + self.t2)

    @property
    def duration(self) -> float:
        return 4.0 * self.tj + 2.0 * self.t2 + self.t4

    @property
    def speed(self) -> float:
        """Speed gained [m/s]."""
        return self.peak_accel * (2.0 * self.tj + self.t2 + self.t4)

    @property
    def distance(self) -> float:
        """Distance covered from rest [m]: the velocity curve is point-symmetric about
        its middle, so half the final speed times the duration."""
        return self.speed * self.duration / 2.0


def _phase_to(speed: float, tj: float, jm: float, accel: float) -> AccelPhase:
    """The acceleration phase from rest to ``speed`` with pulse ``tj``, jerk ``jm`` and
    acceleration limit ``accel`` (module docstring)."""
    if speed >= accel * tj + accel**2 / jm:
        t2 = accel / jm - tj
        return AccelPhase(tj, jm, t2, speed / accel - (tj + accel / jm))
    peak = jm * (-tj + math.sqrt(tj**2 + 4.0 * speed / jm)) / 2.0
    return AccelPhase(tj, jm, max(peak / jm - tj, 0.0), 0.0)


@dataclass(frozen=True)
class RestToRestLeg:
    """A straight leg of ``length`` [m] flown from rest to rest (module docstring)."""

    length: float
    phase: AccelPhase  #: acceleration (the deceleration mirrors it)
    cruise: float  #: constant-speed time [s]

    @classmethod
    def plan(cls, length: float, speed: float, limits: JerkLimits) -> RestToRestLeg:
        """The profile ArduPilot builds for ``length`` at speed limit ``speed``."""
        if length <= 0.0:
            return cls(0.0, AccelPhase(0.0, 0.0, 0.0, 0.0), 0.0)
        jerk, snap, accel = limits.jerk, limits.snap, limits.accel
        tj = jerk * math.pi / (2.0 * snap)
        jm = jerk
        if min(accel, speed / (2.0 * tj), (length / 2.0) / (4.0 * tj**2)) < jerk * tj:
            tj = min(
                tj,
                (length * math.pi / (16.0 * snap)) ** 0.25,
                (speed * math.pi / (4.0 * snap)) ** (1.0 / 3.0),
                math.sqrt(accel * math.pi / (2.0 * snap)),
            )
            jm = 2.0 * snap * tj / math.pi
            accel = jm * tj
        phase = _phase_to(speed, tj, jm, accel)
        if 2.0 * phase.distance <= length:
            return cls(length, phase, (length - 2.0 * phase.distance) / speed)
        low, high = 0.0, speed  # the peak speed whose two phases cover the length
        for _ in range(BISECTION_STEPS):
            middle = (low + high) / 2.0
            if 2.0 * _phase_to(middle, tj, jm, accel).distance > length:
                high = middle
            else:
                low = middle
        return cls(length, _phase_to(low, tj, jm, accel), 0.0)

    @property
    def duration(self) -> float:
        return 2.0 * self.phase.duration + self.cruise

    @property
    def peak_speed(self) -> float:
        return self.phase.speed

    def jerk_at(self, t: NDArray[np.float64]) -> NDArray[np.float64]:
        """Jerk along the leg at times ``t`` [s] from its start."""
        p = self.phase
        t = np.asarray(t, dtype=float)
        one = self._phase_jerk(t, p)
        # deceleration: the speed is the acceleration's time-reversed, v(t) = v(T - t), so
        # the jerk is too: j(t) = j_acc(T - t)
        mirrored = self._phase_jerk(self.duration - t, p)
        into_decel = t >= p.duration + self.cruise
        return np.where(t < p.duration, one, np.where(into_decel, mirrored, 0.0))

    @staticmethod
    def _phase_jerk(t: NDArray[np.float64], p: AccelPhase) -> NDArray[np.float64]:
        if p.tj <= 0.0:
            return np.zeros_like(t)
        edges = np.cumsum([p.tj, p.t2, p.tj, p.t4, p.tj, p.t2, p.tj])
        w = np.pi / p.tj
        rise = p.jm / 2.0 * (1.0 - np.cos(w * t))
        fall = p.jm / 2.0 * (1.0 + np.cos(w * (t - edges[1])))
        down = -p.jm / 2.0 * (1.0 - np.cos(w * (t - edges[3])))
        back = -p.jm / 2.0 * (1.0 + np.cos(w * (t - edges[5])))
        return np.select(
            [t < 0, t < edges[0], t < edges[1], t < edges[2], t < edges[3], t < edges[4],
             t < edges[5], t < edges[6]],
            [0.0, rise, p.jm, fall, 0.0, down, -p.jm, back],
            default=0.0,
        )  # fmt: skip

    def distance_at(self, t: NDArray[np.float64], step: float = 1e-3) -> NDArray[np.float64]:
        """Distance along the chord [m] at times ``t`` [s] from the leg's start (clamped to
        the leg), by integrating the jerk three times on a ``step`` grid."""
        t = np.clip(np.asarray(t, dtype=float), 0.0, self.duration)
        if self.length == 0.0:
            return np.zeros_like(t)
        n = max(math.ceil(self.duration / step), 2)
        grid = np.linspace(0.0, self.duration, n + 1)
        dt = grid[1] - grid[0]
        jerk = self.jerk_at(grid)
        accel = np.concatenate([[0.0], np.cumsum((jerk[1:] + jerk[:-1]) / 2.0) * dt])
        speed = np.concatenate([[0.0], np.cumsum((accel[1:] + accel[:-1]) / 2.0) * dt])
        distance = np.concatenate([[0.0], np.cumsum((speed[1:] + speed[:-1]) / 2.0) * dt])
        # the profile is exact; the integration error is scaled out at the end
        distance *= self.length / distance[-1]
        return np.interp(t, grid, distance)
