"""The mock's own straight legs (NAV_WAYPOINT, takeoff, landing): a speed profile with a
bounded along-track acceleration, not ArduCopter's S-curve (:mod:`.kinematic_flight`)."""

from __future__ import annotations

import math
from dataclasses import dataclass


@dataclass(frozen=True)
class SpeedProfile:
    """Along-track motion over one leg: the speed ramps at +-``accel`` from ``v_in`` to
    ``v_peak``, holds it for ``cruise_s``, and ramps to ``v_out`` [m, m/s, m/s^2, s]."""

    length: float
    v_in: float
    v_peak: float
    v_out: float
    accel: float
    cruise_s: float

    @classmethod
    def plan(
        cls, length: float, v_in: float, cruise: float, v_exit: float, accel: float
    ) -> SpeedProfile:
        """The fastest profile entering at ``v_in`` that never exceeds ``cruise`` (unless it
        enters faster and must first slow down) and passes the end at ``v_exit``; if the leg
        is too short to reach ``v_exit``, it ends at the speed the ramp reaches."""
        reach = 2.0 * accel * length
        if v_in**2 >= v_exit**2 + reach:  # cannot slow down to v_exit: brake all the way
            return cls(length, v_in, v_in, math.sqrt(v_in**2 - reach), accel, 0.0)
        if v_exit**2 >= v_in**2 + reach:  # cannot speed up to v_exit: accelerate all the way
            return cls(length, v_in, v_in, math.sqrt(v_in**2 + reach), accel, 0.0)
        # the triangle's apex, or cruise; entering above cruise, the apex exceeds v_in and
        # the profile slows down to cruise first
        peak = min(cruise, math.sqrt((reach + v_in**2 + v_exit**2) / 2.0))
        ramps = (abs(peak**2 - v_in**2) + abs(peak**2 - v_exit**2)) / (2.0 * accel)
        return cls(length, v_in, peak, v_exit, accel, max(length - ramps, 0.0) / peak)

    def _ramp(self, v_from: float, v_to: float) -> tuple[float, float]:
        duration = abs(v_to - v_from) / self.accel
        return duration, 0.5 * (v_from + v_to) * duration

    @property
    def duration(self) -> float:
        return (abs(self.v_peak - self.v_in) + abs(self.v_peak - self.v_out)) / self.accel + (
            self.cruise_s
        )

    def at(self, t: float) -> tuple[float, float]:
        """Distance along the leg [m] and speed [m/s] at ``t`` [s] after its start."""
        t1, d1 = self._ramp(self.v_in, self.v_peak)
        t2, t3 = self.cruise_s, abs(self.v_peak - self.v_out) / self.accel
        if t < t1:
            change = (1.0 if self.v_peak >= self.v_in else -1.0) * self.accel
            return self.v_in * t + 0.5 * change * t * t, self.v_in + change * t
        if t < t1 + t2:
            return d1 + self.v_peak * (t - t1), self.v_peak
        tau = min(t - t1 - t2, t3)
        sign = 1.0 if self.v_out >= self.v_peak else -1.0
        distance = d1 + self.v_peak * t2 + self.v_peak * tau + 0.5 * sign * self.accel * tau**2
        return min(distance, self.length), self.v_peak + sign * self.accel * tau
