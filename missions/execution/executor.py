"""Playing the plan from one clock: what the stream and the onboard executors share.

An executor holds the group clock (:mod:`.group_clock`), watches the team
(:mod:`.team`) and keeps an :class:`ExecutionRecord`. Every tick (``rate_hz`` a second of
the vehicles' time) it

1. takes the present: the latest common time any vehicle has reached (:mod:`.vehicles`);
2. judges the team: new faults stop the clock for all three; each drone's distance to its
   target and the formation's distance errors steer the clock's rate (the rule of
   :class:`~.group_clock.RatePolicy`);
3. hands the clock to the vehicles (:meth:`Executor._command`): targets to each drone
   (:mod:`.stream`), or the clock itself to players on board (:mod:`.onboard`).

Sequence: :meth:`Executor.prepare` (telemetry, clocks, frames), ``engage`` (the subclass's
hand-over from the hold), :meth:`start` (plan time 0 ``start_delay`` of common time later),
:meth:`wait` until the plan's end or a stop, :meth:`stop`.
"""

from __future__ import annotations

import logging
import threading
import time
from abc import ABC, abstractmethod
from collections.abc import Sequence
from dataclasses import asdict, replace
from functools import partial
from itertools import combinations

import numpy as np
from numpy.typing import NDArray

from missions.autopilots.location import VehicleFrame
from missions.execution.anchor import Anchor, FormationRoom
from missions.execution.group_clock import GroupClock
from missions.execution.options import ExecutionOptions
from missions.execution.record import ExecutionRecord
from missions.execution.team import Fault, FaultKind, TeamMonitor
from missions.execution.vehicles import VehicleState
from missions.mavlink.commands import send_command, set_message_interval
from missions.mavlink.errors import MavlinkError
from missions.mavlink.guided import request_message, set_mode_message
from missions.mavlink.policy import RetryPolicy
from missions.mavlink.transport import VehicleLink
from missions.options import GeodeticOrigin
from missions.trajectory.drone_trajectory import DroneTrajectory

logger = logging.getLogger(__name__)

#: The longest pause of the host's (the ground's, or a simulator's) that is not a
#: vehicle's silence [s of wall time] (module docstring of :mod:`.team`, ``link``). Faster
#: than real time it counts ``speedup`` times over in the vehicles' time, so a lost link
#: is never judged on less than this much of wall time (:meth:`Executor.__init__`): 0.5 s
#: at x5, where a simulator starved of a 2-core host's time can lag the others by more
#: (BENCHMARKS.md "A lost link in real time"); in real time the timeout's own 0.2 s.
GROUND_PAUSE_S = 0.1
#: Faults after which the drone still flies under its own control, with an estimate the
#: team can follow to the stop (:meth:`Executor._follow`). Not one that cannot follow its
#: targets (a weak motor): it wanders, and following its progress along the plan spread
#: the team 0.45 m apart (p95) on the Puzzle; in the stream the other two follow its
#: deviation instead, as little as keeps the load safe (:mod:`.anchor`).
FOLLOWED = (FaultKind.MODE, FaultKind.FAILSAFE)
#: How far from the clock's plan time a followed drone's progress is looked for [s].
FOLLOW_WINDOW_S = 3.0
#: The clock's rate per second of plan time between it and a followed drone [1/s].
FOLLOW_GAIN = 2.0
#: A vehicle not heard for this long [s of common time] does not steer the clock: its
#: estimate is too old to say how it keeps up, and a clock changed now might not reach it.
STALE_S = 0.2
#: A target slower than this [m/s] has no direction to lag along.
MOVING = 0.02
#: Telemetry an execution asks each vehicle for, and how often [s of vehicle time].
STREAMS = {
    "LOCAL_POSITION_NED": 0.04,
    "HEARTBEAT": 0.1,
    "GPS_RAW_INT": 0.1,
    "EKF_STATUS_REPORT": 0.1,
    "ATTITUDE": 0.05,
    "NAV_CONTROLLER_OUTPUT": 0.05,
    "SYSTEM_TIME": 0.5,
}


class Executor(ABC):
    """Plays a :class:`DroneTrajectory` on three vehicles from one clock (module
    docstring). Subclasses hand the clock over: :meth:`engage`, :meth:`_command`."""

    mode = ""  #: the record's name of the executor
    expected_mode = 0  #: the flight mode every drone must stay in (ArduCopter's number)
    #: Whether a lost link stops the team: it must where the ground flies the drone; an
    #: onboard player keeps the clock through it, and a stop it cannot hear would split
    #: the team.
    link_loss_stops = True
    #: How far ahead of a vehicle's present its targets are (horizontal, vertical) [s]
    #: unless :attr:`ExecutionOptions.lead` says: ArduCopter 4.5.7's position controller,
    #: default tuning, lags a horizontal target more than a vertical one, the stream's
    #: targets and the onboard player's alike once their clocks agree (BENCHMARKS.md,
    #: "Execution in step", "Second run"; "Targets in the vehicles' own metres").
    default_lead: tuple[float, float] = (0.05, 0.0)
    #: From the start command to plan time 0 [s of common time] unless
    #: :attr:`ExecutionOptions.start_delay` says: long enough for the drones to reach their
    #: first target from the autopilot's own hold (which ArduCopter flies at whole
    #: centimetres of altitude, and the SITL harness releases within 2 cm of). 4.5.7
    #: closes the last centimetre of height in about 2 s; started after 1 s, the drones
    #: began up to 1.7 cm below their start and the Puzzle's 20-40 ms further apart
    #: (BENCHMARKS.md, "Execution in step", "Third run").
    default_start_delay = 3.0
    #: Whether the other two follow a drone that cannot keep its targets (:mod:`.anchor`):
    #: where the ground sends every target.
    anchors = False

    def __init__(
        self,
        links: Sequence[VehicleLink],
        trajectory: DroneTrajectory,
        origin: GeodeticOrigin,
        options: ExecutionOptions | None = None,
        speedup: float = 1.0,
        retry: RetryPolicy | None = None,
        room: FormationRoom | None = None,
    ) -> None:
        if len(links) != 3:
            raise ValueError(f"three vehicles, not {len(links)}")
        self.links, self.trajectory, self.origin = list(links), trajectory, origin
        self.options = options or ExecutionOptions()
        self.speedup, self.retry, self.room = speedup, retry or RetryPolicy(), room
        self.vehicles = [
            VehicleState(link, speedup, self.options.max_extrapolation) for link in links
        ]
        limits = self.options.limits
        if limits.link_timeout < GROUND_PAUSE_S * speedup:
            limits = replace(limits, link_timeout=GROUND_PAUSE_S * speedup)
        self.monitor = TeamMonitor(self.expected_mode, limits)
        self.frames: list[VehicleFrame] = []
        self.clock: GroupClock | None = None
        self.record: ExecutionRecord | None = None
        self.cut: set[int] = set()  #: drones whose link the ground lost (0-based)
        #: drones (0-based) held at their start this long [s] after the plan's start
        self.held: dict[int, float] = {}
        self._thread: threading.Thread | None = None
        self._stop = threading.Event()
        self._done = threading.Event()
        self._stopping = False
        self._leader: int | None = None  #: a faulty drone the stopping team follows
        self._anchor: tuple[int, Anchor] | None = None  #: one the other two follow
        self._sign = 1.0  #: -1 while retreating along the plan
        self._lock = threading.Lock()

    # setting up ------------------------------------------------------------------------

    def prepare(self, timeout: float) -> None:
        """Ask for the telemetry, each vehicle's home and EKF origin, and wait until every
        clock and frame is known (``timeout`` [s of ground time]).

        Raises
        ------
        MavlinkError
            A vehicle refused or did not answer a request.
        TimeoutError
            A clock or a frame is still unknown at the deadline.
        """
        for link in self.links:
            for name, interval in STREAMS.items():
                set_message_interval(link, name, interval, self.retry)
        deadline = time.monotonic() + timeout
        home_up = float(self.trajectory.homes[0, 2])
        while True:
            for link, vehicle in zip(self.links, self.vehicles, strict=True):
                if vehicle.home_down is None:
                    self._request(link, "HOME_POSITION")
                if vehicle.origin is None:
                    self._request(link, "GPS_GLOBAL_ORIGIN")
            frames = [v.frame(self.origin, home_up) for v in self.vehicles]
            known = [
                f is not None and v.offset is not None
                for f, v in zip(frames, self.vehicles, strict=True)
            ]
            if all(known):
                self.frames = [f for f in frames if f is not None]
                return
            if time.monotonic() > deadline:
                missing = [link.name for link, ok in zip(self.links, known, strict=True) if not ok]
                raise TimeoutError(f"no clock or frame of {missing} within {timeout:.0f} s")
            time.sleep(0.05)

    def _request(self, link: VehicleLink, name: str) -> None:
        try:
            send_command(link, *request_message(name), self.retry)
        except MavlinkError as error:
            logger.info("%s: %s not given yet: %s", link.name, name, error)

    @abstractmethod
    def engage(self, timeout: float) -> None:
        """Hand the drones over from their hold to the executor."""

    def start(self) -> ExecutionRecord:
        """Start the plan ``start_delay`` of common time from now, and play it (a
        background thread) until :meth:`stop` or the plan's end."""
        now = self.present()
        delay = self.options.start_delay
        delay = self.default_start_delay if delay is None else delay
        self.clock = GroupClock(now + delay, self.trajectory.duration)
        self.record = ExecutionRecord(
            mode=self.mode,
            start=self.clock.start,
            duration=self.trajectory.duration,
            offsets=[float(v.offset or 0.0) for v in self.vehicles],
            frames=[asdict(f) for f in self.frames],
        )
        self._thread = threading.Thread(target=self._run, name=f"{self.mode}-executor",
                                        daemon=True)  # fmt: skip
        self._thread.start()
        return self.record

    # running ---------------------------------------------------------------------------

    def present(self) -> float:
        """The latest common time any vehicle has reached."""
        times = [v.common_time() for v in self.vehicles]
        known = [t for k, t in enumerate(times) if t is not None and k not in self.cut]
        if not known:
            raise RuntimeError("no vehicle's clock is known")
        return max(known)

    def target(self, k: int, t: float) -> tuple[NDArray, NDArray, NDArray]:
        """Drone k's target at common time ``t`` (plan time 0 before the clock exists):
        home-relative ENU position, and velocity and acceleration scaled by the clock's
        rate (module docstring of :mod:`.stream`)."""
        if self.clock is None:
            p, v, a = self.trajectory.at(0.0)
            return p[k], v[k] * 0.0, a[k] * 0.0
        tau, rate, slope = self.clock.state(t)
        p, v, a = self.trajectory.at(tau)
        return p[k], v[k] * rate, a[k] * rate * rate + v[k] * slope

    @property
    def lead(self) -> tuple[float, float]:
        """(horizontal, vertical) [s]: the options' or the executor's own."""
        return self.options.lead if self.options.lead is not None else self.default_lead

    def commanded(self, k: int, t: float) -> tuple[NDArray, NDArray, NDArray]:
        """What drone k is told at ``t``: its :meth:`target`, or its start while it is held
        back (:meth:`hold_back`)."""
        if self.clock is not None and t < self.clock.start + self.held.get(k, -np.inf):
            p, v, a = self.trajectory.at(0.0)
            return p[k], v[k] * 0.0, a[k] * 0.0
        p, v, a = self.target(k, t)
        dp, dv, da = self._shift(k, t)
        return p + dp, v + dv, a + da

    def _shift(self, k: int, t: float) -> tuple[NDArray, NDArray, NDArray]:
        """How far drone k's target (position, velocity, acceleration) moves with a faulty
        drone (:mod:`.anchor`)."""
        if self._anchor is None or self._anchor[0] == k:
            return np.zeros(3), np.zeros(3), np.zeros(3)
        return self._anchor[1].shift(t)

    def _errors(
        self, t: float
    ) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
        """At each drone's last estimate: how far it is behind its target along the
        target's velocity, and its distance to it; and each pair's distance error against
        the plan [m]. Each drone's deviation is taken at its own estimate's time and the
        pairs are compared at the plan's present with those deviations, so that estimates
        a few hundredths of a second apart do not read as a formation error. Only the lag
        and the formation steer the clock: an offset across the path does not shrink by
        waiting."""
        behind, tracking = np.zeros(3), np.zeros(3)
        deviations: list[NDArray[np.float64] | None] = []
        for k, vehicle in enumerate(self.vehicles):
            estimate = vehicle.estimate()
            if estimate is None or k in self.cut:
                deviations.append(None)
                continue
            at, ned = estimate
            task = self.frames[k].task_position(ned)
            p, v, _ = self.target(k, at)
            error = task - (p + self._shift(k, at)[0] + self.trajectory.homes[k])
            tracking[k] = float(np.linalg.norm(error))
            speed = float(np.linalg.norm(v))
            if speed > MOVING:
                behind[k] = max(0.0, -float(error @ v) / speed)
            deviations.append(error)
        tau = self.clock.tau(t) if self.clock is not None else 0.0
        planned = self.trajectory.in_task_frame(self.trajectory.at(tau)[0])
        formation = [
            abs(np.linalg.norm(planned[i] + di - planned[j] - dj)
                - np.linalg.norm(planned[i] - planned[j]))
            for (i, di), (j, dj) in combinations(enumerate(deviations), 2)
            if di is not None and dj is not None
        ]  # fmt: skip
        return behind, tracking, np.array(formation)

    def _judge(self, t: float) -> list[Fault]:
        """Faults first seen at ``t``, the team stop, and the clock's rate (module
        docstring)."""
        assert self.clock is not None and self.record is not None
        behind, tracking, formation = self._errors(t)
        now = time.monotonic()
        stale = False
        for k, vehicle in enumerate(self.vehicles):
            if k in self.cut:
                continue
            heard = vehicle.last_heard()
            if vehicle.heard is not None and heard is not None:
                # silence on the vehicle's own clock against the others' present, which a
                # pause of the ground's cannot fake; and, for a ground that hears no one,
                # in ground time less the ground's own pauses (faster than real time, a
                # reader thread that waits its turn for Python's lock for a tenth of a
                # second would be a second of the vehicles' silence)
                silent = max(now - vehicle.heard - GROUND_PAUSE_S, 0.0) * self.speedup
                heard = min(heard, t - silent)
                self.monitor.heard(k, heard)
                silence = t - heard
                stale |= silence > STALE_S
                self.record.silences[k] = max(self.record.silences[k], silence)
            self.monitor.observe(
                k,
                mode=vehicle.mode,
                system_status=vehicle.system_status,
                ekf_flags=vehicle.ekf_flags,
                fix_type=vehicle.fix_type,
                error=float(tracking[k]),
                attitude_error=vehicle.attitude_error(),
            )
        faults = self.monitor.faults(t)
        # a drone the ground cannot hear is sent nothing more, and counts no more
        lost = {f.drone - 1 for f in faults if f.kind is FaultKind.LINK}
        for k in lost - self.cut:
            self._lost(k)
        self.cut |= lost
        stopping = [f for f in faults if f.kind is not FaultKind.LINK or self.link_loss_stops]
        if stopping and not self._stopping:
            self._stopping = True
            self.record.commanded_stop_at = t
            if stopping[0].kind in FOLLOWED:
                self._leader = stopping[0].drone - 1
            logger.warning("team stop: %s", "; ".join(map(str, stopping)))
        self._anchor_on_weak(stopping)
        for fault in faults:
            self.record.faults.append({**asdict(fault), "kind": str(fault.kind)})
        if (self.cut or stale) and not self.link_loss_stops:
            return faults  # a drone that may not hear the clock keeps the one it has
        if stale and not self._stopping:
            return faults  # a drone not heard of late says nothing of the team's pace
        start = max(t, self.clock.segments[-1].start)
        if self._stopping and self._leader is not None:
            self._follow(self._leader, start)
            return faults
        badness = self.options.policy.badness(behind, formation)
        self.options.policy.steer(self.clock, start, badness, stop=self._stopping, sign=self._sign)
        return faults

    def _anchor_on_weak(self, faults: list[Fault]) -> None:
        """The other two follow the first drone seen weak (an attitude fault) that the ground
        still flies (:mod:`.anchor`): at the team stop it caused, or during the hold after
        another fault stopped the team, where braked at their stops they let a cable go
        slack as it swings (BENCHMARKS.md "A weak motor during a hold")."""
        if not self.anchors or not self._stopping or self._anchor is not None:
            return
        assert self.clock is not None
        weak = [f.drone - 1 for f in faults if f.kind is FaultKind.ATTITUDE]
        weak = [k for k in weak if k not in self.cut and k != self._leader]
        if weak:
            k = weak[0]
            anchor = Anchor(self.vehicles[k], self.frames[k], self.trajectory.homes[k],
                            partial(self.target, k), self.clock.tau, k, self.room)  # fmt: skip
            self._anchor = (k, anchor)

    def _follow(self, k: int, t: float) -> None:
        """Steer the clock to drone k's progress (the plan time whose position of drone k is
        nearest its estimate, within :data:`FOLLOW_WINDOW_S` of the clock's): a drone that
        flies on its own after its fault (another mode, a failsafe, a weak motor) stops
        where its own controller stops it, and the other two stop at the plan's positions
        beside it rather than wherever the clock's braking would leave them."""
        assert self.clock is not None
        estimate = self.vehicles[k].estimate()
        if estimate is None:
            self.options.policy.steer(self.clock, t, 0.0, stop=True)
            return
        tau = self.clock.tau(t)
        here = self.frames[k].task_position(estimate[1])
        gap = self.trajectory.nearest_time(k, here, tau, FOLLOW_WINDOW_S) - tau
        target = 0.0 if abs(gap) < 0.02 else float(np.clip(FOLLOW_GAIN * gap, -1.0, 1.0))
        if abs(target - self.clock.target) > 0.02:
            self.clock.steer(t, target, self.options.policy.braking)

    def _lost(self, k: int) -> None:  # noqa: B027 - a hook; nothing to do by default
        """Drone k's link was found lost (before it counts no more)."""

    @abstractmethod
    def _command(self, t: float) -> None:
        """Hand the clock to the vehicles at common time ``t``."""

    def restore_mode(self, drone: int) -> None:
        """Put ``drone`` (1-based) back into the execution's flight mode (the operator
        taking a drone back from a switch or a failsafe, before :meth:`resume`)."""
        link = self.links[drone - 1]
        link.send(set_mode_message(self.expected_mode, link.target))

    def _run(self) -> None:
        assert self.clock is not None and self.record is not None
        period = 1.0 / (self.options.rate_hz * self.speedup)
        next_tick = time.monotonic()
        try:
            while not self._stop.is_set():
                t = self.present()
                with self._lock:
                    self._judge(t)
                    self._command(t)
                    self.record.ticks += 1
                    tau, rate, _ = self.clock.state(t)
                    if self._stopping and rate == 0.0 and self.record.stopped_at is None:
                        self.record.stopped_at = t
                    if tau >= self.clock.duration and t > self.clock.start:
                        self._done.set()
                next_tick += period
                self._stop.wait(max(next_tick - time.monotonic(), 0.0))
        except Exception:
            logger.exception("%s executor failed", self.mode)
            self._done.set()
            raise
        finally:
            self.record.segments = [asdict(s) for s in self.clock.segments]

    def lose_link(self, drone: int) -> None:
        """Stop hearing ``drone`` (1-based), as a lost link would (a fault injection): the
        team failsafe finds it by its silence."""
        self.vehicles[drone - 1].deaf = True

    def resume(self) -> None:
        """After a team stop, go on along the plan (the operator's call, once the faulty
        drone flies as commanded again).

        Raises
        ------
        RuntimeError
            A drone is still faulty or out of reach.
        """
        self._carry_on(sign=1.0)

    def retreat(self) -> None:
        """After a team stop, fly the plan backwards to its start, all three together on
        the group clock: the way the load came is the way known to be safe, and at the
        start it is back where it was lifted from (the operator's call).

        Raises
        ------
        RuntimeError
            A drone is still faulty or out of reach.
        """
        self._carry_on(sign=-1.0)

    def _carry_on(self, sign: float) -> None:
        with self._lock:
            t = self.present()
            active = [(k + 1, kind) for k in range(3) for kind, _ in self.monitor.current(k, t)] + [
                (k + 1, "link") for k in sorted(self.cut)
            ]
            if active:
                raise RuntimeError(f"the team cannot go on: faults {active}")
            self._stopping, self._sign, self._leader, self._anchor = False, sign, None, None
            self.monitor.reported.clear()  # a fault that comes back stops the team again
            self._done.clear()

    @property
    def at_start(self) -> bool:
        """Whether the plan is back at its start and still (a retreat's end)."""
        if self.clock is None:
            return False
        return self.clock.state(self.present()) == (0.0, 0.0, 0.0)

    def hold_back(self, drone: int, seconds: float) -> None:
        """Keep ``drone`` (1-based) at its start for ``seconds`` of common time after the
        plan's start: a late start (a fault injection), which the group clock absorbs."""
        self.held[drone - 1] = seconds

    def wait(self, timeout: float) -> bool:
        """Until the plan's end (True) or ``timeout`` [s of ground time] (False); a stopped
        plan never ends."""
        return self._done.wait(timeout)

    @property
    def stopped(self) -> bool:
        """Whether a team stop went out."""
        return self._stopping

    def stop(self) -> ExecutionRecord:
        """Stop playing and return the record (the vehicles hold their last targets)."""
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=5.0)
        for vehicle in self.vehicles:
            vehicle.close()
        assert self.record is not None
        return self.record
