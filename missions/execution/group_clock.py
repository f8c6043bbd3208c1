"""Group time: the one clock the three drones play their trajectories from.

Plan time tau is a function of *common time* t (GPS time on real vehicles; on SITL each
simulator's clock, started from one epoch): a chain of segments over which the rate
d tau / d t changes linearly, like Skybrush's time axis. Every vehicle evaluates the same
function against its own copy of the common clock, so all three agree on where the plan is
whatever reaches them late; the ground changes the rate only from the present on, never in
the past.

The rate rule (:class:`RatePolicy`), written down with its reasons:

- The plan is only safe where the three drones are at its positions *together*. So the
  rate falls as the worst *badness* among the drones grows: how far each drone is behind
  its target (along the target's velocity) over the tracking tolerance, and each pair's
  distance error against the plan's over the formation tolerance. An offset across the
  path, or a steady one, does not shrink by waiting: it counts through the formation.
  Below ``slow_from`` of a tolerance the group runs at full rate; at the tolerance it
  stops; linear between. A drone that starts late or flies slow falls behind, and the
  other two slow down with it instead of pulling the formation apart.
- The rate changes at most ``slowing`` per second down and ``speeding`` per second up:
  drones braking together at the same rate stay in formation (the feed-forward carries
  the rate's change, :meth:`GroupClock.state`), and a recovery does not jerk the load.
  Every change of the rate is an acceleration of the whole team (the plan's velocity
  times the rate's slope: 0.5 m/s² at 0.5 m/s and 1/s), so the target rate moves only
  by more than ``deadband``: a clock that hunts after the estimates' noise shakes the
  drones off their targets and feeds the noise it follows.
- A fault (:mod:`missions.execution.team`) forces the target to 0 at ``braking`` (2/s:
  from full rate to a stop in 0.5 s, a drone at the plan's 0.5 m/s travelling 12.5 cm).
  A drone that flies on under its own control (another mode, a failsafe) is followed
  instead: the clock seeks its progress, so that the others stop beside it
  (:meth:`missions.execution.executor.Executor._follow`).

Limits: the rule sees what the drones report (their estimates), not where they truly are;
it can wait for a drone, not move one that cannot fly; and a drone whose link is lost keeps
its last targets only for ArduPilot's GUID_TIMEOUT (the onboard player keeps the clock).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


@dataclass(frozen=True)
class Segment:
    """From common time ``start`` on, plan time ``tau`` advances at a rate going linearly
    from ``rate`` to ``rate_end`` over ``ramp`` seconds, then staying at ``rate_end``."""

    start: float  #: common time [s]
    tau: float  #: plan time at ``start`` [s]
    rate: float
    rate_end: float
    ramp: float  #: [s]; 0: the rate is ``rate_end`` from ``start`` on

    def state(self, t: float) -> tuple[float, float, float]:
        """(tau, rate, d rate / d t) at common time ``t`` >= ``start``."""
        dt = max(t - self.start, 0.0)
        if self.ramp > 0.0 and dt < self.ramp:
            slope = (self.rate_end - self.rate) / self.ramp
            return self.tau + self.rate * dt + 0.5 * slope * dt * dt, self.rate + slope * dt, slope
        ramped = self.tau + 0.5 * (self.rate + self.rate_end) * self.ramp
        return ramped + self.rate_end * (dt - self.ramp), self.rate_end, 0.0


@dataclass
class GroupClock:
    """Plan time as a function of common time (module docstring), held between 0 and
    ``duration``: before the start the plan waits at 0, after its end at ``duration``."""

    start: float  #: common time of plan time 0 [s]
    duration: float  #: the plan's duration [s]
    segments: list[Segment] = field(default_factory=list)

    def __post_init__(self) -> None:
        if not self.segments:
            self.segments.append(Segment(self.start, 0.0, 1.0, 1.0, 0.0))

    def _segment(self, t: float) -> Segment:
        for segment in reversed(self.segments):
            if t >= segment.start:
                return segment
        return self.segments[0]

    def state(self, t: float) -> tuple[float, float, float]:
        """(tau, rate, d rate / dt) at common time ``t``; the rate is 0 outside the plan."""
        if t <= self.start:
            return 0.0, 0.0, 0.0
        tau, rate, slope = self._segment(t).state(t)
        if tau >= self.duration and rate >= 0.0:
            return self.duration, 0.0, 0.0
        if tau <= 0.0 and rate <= 0.0:
            return 0.0, 0.0, 0.0
        return tau, rate, slope

    def tau(self, t: float) -> float:
        return self.state(t)[0]

    def steer(self, t: float, target: float, slope: float) -> None:
        """From common time ``t`` on, move the rate towards ``target`` at ``slope`` [1/s].

        ``t`` must not precede the last change (the past is never rewritten)."""
        last = self.segments[-1]
        if t < last.start:
            raise ValueError(f"steer at {t} before the last change at {last.start}")
        tau, rate, _ = last.state(t)
        if rate == target and last.rate_end == target:
            return
        ramp = abs(target - rate) / slope if slope > 0 else 0.0
        self.segments.append(Segment(t, tau, rate, target, ramp))

    def rejoin(self, t: float, segment: Segment) -> None:
        """From common time ``t`` on, run as ``segment`` runs: the law of a drone that
        heard no later change (a player whose link was lost keeps the last one it got)."""
        if t < self.segments[-1].start:
            raise ValueError(f"rejoin at {t} before the last change at {self.segments[-1].start}")
        tau, rate, _ = segment.state(t)
        ramp = max(segment.start + segment.ramp - t, 0.0)
        self.segments.append(Segment(t, tau, rate, segment.rate_end, ramp))

    @property
    def target(self) -> float:
        """The rate the clock is heading for."""
        return self.segments[-1].rate_end


@dataclass(frozen=True)
class RatePolicy:
    """How the group rate follows the drones (module docstring)."""

    tracking_tolerance: float = 0.10  #: how far behind its target a drone stops the plan [m]
    formation_tolerance: float = 0.10  #: a pair's distance error that stops the plan [m]
    slow_from: float = 0.5  #: fraction of a tolerance at which the rate starts to fall
    slowing: float = 1.0  #: largest fall of the rate per second while steering [1/s]
    braking: float = 2.0  #: the fall of the rate in a team stop [1/s]
    speeding: float = 0.5  #: largest rise of the rate per second [1/s]
    deadband: float = 0.05  #: changes of the target rate smaller than this are ignored

    def badness(self, tracking: np.ndarray, formation: np.ndarray) -> float:
        """The worst drone's lag behind its target and the worst pair's distance error,
        each over its tolerance."""
        worst = 0.0
        if tracking.size:
            worst = max(worst, float(np.max(tracking)) / self.tracking_tolerance)
        if formation.size:
            worst = max(worst, float(np.max(formation)) / self.formation_tolerance)
        return worst

    def target_rate(self, badness: float) -> float:
        """1 below ``slow_from``, 0 at 1 (a tolerance reached), linear between."""
        return float(np.clip((1.0 - badness) / (1.0 - self.slow_from), 0.0, 1.0))

    def steer(
        self, clock: GroupClock, t: float, badness: float, stop: bool = False, sign: float = 1.0
    ) -> None:
        """Steer ``clock`` from common time ``t`` on: towards :meth:`target_rate` (backwards
        with ``sign`` -1: a retreat along the plan), or to a stop (``stop``: a fault)."""
        rate_wanted = self.target_rate(badness)
        if rate_wanted > 1.0 - self.deadband:
            rate_wanted = 1.0  # within the deadband of full rate is full rate
        target = 0.0 if stop else sign * rate_wanted
        _, rate, _ = clock._segment(t).state(t)
        if stop:
            slope = self.braking
        else:
            slope = self.slowing if abs(target) < abs(rate) else self.speeding
        # steer only when the heading changes by more than the deadband (noise in the
        # estimates must not make the clock hunt: each change of the rate is an
        # acceleration of the whole team), and always to a stop
        if abs(target - clock.target) > self.deadband or (
            target in (0.0, sign) and clock.target != target
        ):
            clock.steer(t, target, slope)
