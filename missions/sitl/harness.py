"""Fly a task's three missions on three ArduCopter SITL instances and record the flight.

The procedure is the one a ground station follows with real vehicles (README "Flying the
missions"), with the simulator's own additions marked:

1. start three simulators homed on the ground below each drone's start (seq 0 of its
   mission) [SITL];
2. connect, ask for GLOBAL_POSITION_INT, MISSION_CURRENT and, from SITL, SIM_STATE (the
   simulator's true position) at ``stream_hz``, and wait for every vehicle's position
   estimate (EKF_STATUS_REPORT);
3. set the parameters of the plan (``drone{k}.parm``), each confirmed, plus ARMING_CHECK
   0 [SITL: no RC] (a test may set wrong ones on purpose);
4. upload each mission with read-back verification, and read the plan's parameters back
   (the upload reports every one that differs, ``parameter_differences``);
5. arm and start all three (MISSION_START): they take off and hold at their start in
   NAV_LOITER_UNLIM;
6. once all three hover steadily at the hold (slow, and each estimate within
   ``settle_distance`` of its hold), release them together: MISSION_SET_CURRENT
   to the first timed item, sent back to back (:func:`missions.mavlink.commands.release`);
7. record until every drone holds at its end, then stop.

Everything the vehicles send is written to ``drone{k}.tlog`` (time base: the simulation's,
:class:`~missions.mavlink.tlog.StretchedClock`), and what the ground did and when to
``flight.json``. :mod:`missions.flight_report` reads both.

Pace: each simulator steps by its own clock, so what it computes is right at any pace, and
the flight report aligns the drones at their releases on their own clocks: a loaded
machine that slows the simulators changes nothing but the wall time. A ground station's
command still reaches each simulator at a wall-clock instant, so a simulator that nearly
stalls would take it late in simulated time: the achieved rate of each (SYSTEM_TIME against
the wall clock) is measured and a flight slower than ``min_rate`` of the speed-up is refused
(:class:`SitlError`). Wall-clock waits are sized for that slowest pace.
"""

from __future__ import annotations

import logging
import math
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from missions.export.items import DroneMission, MissionItem
from missions.flight_report.record import FlightRecord, VehicleRecord
from missions.geodesy import DEGREE_UNIT, ardupilot_altitude, enu_from_geodetic
from missions.mavlink.commands import ReleaseReport, release, set_message_interval
from missions.mavlink.fleet import Fleet, on_every_vehicle
from missions.mavlink.policy import RetryPolicy
from missions.mavlink.tlog import StretchedClock, TlogWriter
from missions.mavlink.transport import VehicleLink
from missions.options import GeodeticOrigin
from missions.sitl.errors import SitlError
from missions.sitl.process import SitlGroup, SitlHome
from missions.sitl.settings import SitlSettings
from missions.task.directory import TaskDirectory

logger = logging.getLogger(__name__)

#: Parameters the simulator needs and a real vehicle must not get from us.
SITL_PARAMETERS = {"ARMING_CHECK": 0.0}  # no RC, no pre-arm checks to pass
#: EKF_STATUS_REPORT flags of a usable position estimate: attitude, horizontal and vertical
#: velocity, absolute horizontal and vertical position.
EKF_READY = 1 | 2 | 4 | 16 | 32
#: Messages the flight report needs, besides what the vehicle sends unasked.
RECORDED_STREAMS = ("GLOBAL_POSITION_INT", "SIM_STATE", "MISSION_CURRENT")
#: The time base check: SYSTEM_TIME every this many simulated seconds.
SYSTEM_TIME_INTERVAL_S = 0.5


@dataclass(frozen=True)
class SitlFlightOptions:
    """How a SITL flight is flown and recorded (times in simulated seconds)."""

    stream_hz: float = 50.0
    settle_s: float = 3.0  #: steady hover at the hold before the release
    settle_speed: float = 0.05  #: [m/s] "steady": every drone slower than this
    #: [m] "steady": and every drone's estimate this close to its hold. Slow alone is not
    #: steady: a take-off closes its last centimetres of height slowly
    #: (:mod:`missions.autopilots.ardupilot`), and drones released merely slow start the
    #: mission below their hold (BENCHMARKS.md, "Home height")
    settle_distance: float = 0.02
    end_margin_s: float = 3.0  #: recorded after the last drone reached its end
    #: extra delay of each drone's release [s]: a deliberately perturbed flight
    release_delays: tuple[float, float, float] = (0.0, 0.0, 0.0)
    #: parameters set on each vehicle after the plan's (a deliberately wrong setting)
    parameter_overrides: tuple[Mapping[str, float], ...] = field(default_factory=tuple)


@dataclass(frozen=True)
class FlightPlanFiles:
    """What a flight needs from a task's directory (``flycrane plan`` output)."""

    missions: tuple[DroneMission, ...]
    parameters: tuple[dict[str, float], ...]  #: per drone, from ``drone{k}.parm``
    hold_seq: int  #: the NAV_LOITER_UNLIM at the start
    release_seq: int  #: the item the release jumps to
    end_seq: tuple[int, ...]  #: per drone, its last item (the hold at the end)
    duration_s: float  #: the plan's duration after the release

    @classmethod
    def read(cls, task_dir: Path) -> FlightPlanFiles:
        """From a task's directory (:class:`~missions.task.directory.TaskDirectory`).

        Raises
        ------
        TaskDirectoryError
            A file the flight needs is missing or unreadable.
        """
        directory = TaskDirectory(task_dir)
        missions = directory.missions()
        mission = directory.mission_summary()
        return cls(
            missions=tuple(missions),
            parameters=tuple(directory.parameters()),
            hold_seq=mission.release.hold_seq,
            release_seq=mission.release.release_seq,
            end_seq=tuple(m.items[-1].seq for m in missions),
            duration_s=mission.duration,
        )


def _policy(settings: SitlSettings) -> RetryPolicy:
    # Simulated time runs ``speedup`` times faster, so the vehicles answer in wall
    # milliseconds; the heartbeat waits for the boot (SITL starts on our connection).
    return RetryPolicy(
        request_timeout_s=0.5,
        retries=6,
        deadline_s=60.0,
        no_space_backoff_s=0.2,
        no_space_retry_s=settings.boot_timeout,
        heartbeat_timeout_s=30.0,
        gcs_heartbeat_interval_s=0.2,
    )


def _homes(missions: Sequence[DroneMission]) -> list[SitlHome]:
    return [
        SitlHome(m.items[0].x * 1e-7, m.items[0].y * 1e-7, float(m.items[0].z)) for m in missions
    ]


def _wait_for(
    links: Sequence[VehicleLink],
    types: tuple[str, ...],
    done: Callable[[VehicleLink, Any], bool],
    timeout_s: float,
    what: str,
) -> None:
    """Wait until ``done(link, msg)`` held for a message from every link."""
    pending = {link.name for link in links}
    inboxes = {link.name: link.subscribe(types) for link in links}
    deadline = time.monotonic() + timeout_s
    try:
        while pending:
            if time.monotonic() > deadline:
                raise SitlError(f"{what}: {sorted(pending)} not within {timeout_s:.0f} s")
            for link in links:
                if link.name in pending:
                    msg = inboxes[link.name].get(0.01)
                    if msg is not None and done(link, msg):
                        pending.discard(link.name)
    finally:
        for inbox in inboxes.values():
            inbox.close()


class _RateMeter:
    """Simulated seconds per wall second of every vehicle, from SYSTEM_TIME."""

    def __init__(self, links: Sequence[VehicleLink]) -> None:
        self.first: dict[str, tuple[float, float]] = {}
        self.last: dict[str, tuple[float, float]] = {}
        for link in links:
            link.add_listener(("SYSTEM_TIME",), self._listener(link.name))

    def _listener(self, name: str) -> Callable[[Any], None]:
        def on(msg: Any) -> None:
            sample = (time.monotonic(), msg.time_boot_ms / 1000.0)
            self.first.setdefault(name, sample)
            self.last[name] = sample

        return on

    def rates(self) -> dict[str, float]:
        rates = {}
        for name, (wall0, boot0) in self.first.items():
            wall1, boot1 = self.last[name]
            rates[name] = (boot1 - boot0) / (wall1 - wall0) if wall1 > wall0 else 0.0
        return rates


def _release(
    links: Sequence[VehicleLink],
    seq: int,
    delays: Sequence[float],
    speedup: float,
    policy: RetryPolicy,
) -> ReleaseReport:
    """The synchronized release; with ``delays``, drones released that much later
    [simulated s] (a perturbed flight, for tests of the flight report)."""
    start = time.monotonic()
    reports: dict[str, tuple[float, float]] = {}
    for delay in sorted(set(delays)):
        group = [link for link, d in zip(links, delays, strict=True) if d == delay]
        time.sleep(max(start + delay / speedup - time.monotonic(), 0.0))
        report = release(group, seq, policy)
        for name, sent, confirmed in zip(
            report.vehicles, report.sent_s, report.confirmed_s, strict=True
        ):
            reports[name] = (sent, confirmed)
    names = tuple(link.name for link in links)
    return ReleaseReport(
        names, seq, tuple(reports[n][0] for n in names), tuple(reports[n][1] for n in names)
    )


class _Progress:
    """The latest MISSION_CURRENT and time of every vehicle, and since when it has been
    steady at its hold: slower than ``settle_speed`` [m/s] and its estimate within
    ``settle_distance`` [m] of ``holds`` (reader threads)."""

    def __init__(
        self,
        links: Sequence[VehicleLink],
        holds: Sequence[MissionItem],
        settle_speed: float,
        settle_distance: float,
    ) -> None:
        self.current = {link.name: -1 for link in links}
        self.slow_since: dict[str, float | None] = {link.name: None for link in links}
        self.boot_s = {link.name: 0.0 for link in links}
        self.settle_speed = settle_speed
        self.settle_distance = settle_distance
        # each hold where ArduPilot flies it: its latitude and longitude, and its altitude
        # above home in whole centimetres (relative_alt is above home too)
        self._holds = {
            link.name: GeodeticOrigin(
                latitude=hold.x * DEGREE_UNIT,
                longitude=hold.y * DEGREE_UNIT,
                altitude=float(ardupilot_altitude(hold.z)),
            )
            for link, hold in zip(links, holds, strict=True)
        }
        self._links = links
        for link in links:
            link.add_listener(("MISSION_CURRENT", "GLOBAL_POSITION_INT"), self._listener(link.name))

    def _listener(self, name: str) -> Callable[[Any], None]:
        def on(msg: Any) -> None:
            if msg.get_type() == "MISSION_CURRENT":
                if msg.seq != self.current[name]:
                    self.current[name] = msg.seq
                    self.slow_since[name] = None
                return
            now = msg.time_boot_ms / 1000.0
            self.boot_s[name] = now
            speed = (msg.vx**2 + msg.vy**2 + msg.vz**2) ** 0.5 / 100.0
            offset = enu_from_geodetic(
                msg.lat * DEGREE_UNIT, msg.lon * DEGREE_UNIT, msg.relative_alt / 1000.0,
                self._holds[name],
            )  # fmt: skip
            if speed > self.settle_speed or math.hypot(*offset) > self.settle_distance:
                self.slow_since[name] = None
            elif self.slow_since[name] is None:
                self.slow_since[name] = now

        return on

    def steady_for(self, name: str) -> float:
        since = self.slow_since[name]
        return 0.0 if since is None else self.boot_s[name] - since

    def wait(self, condition: Callable[[], bool], timeout_s: float, what: str) -> None:
        deadline = time.monotonic() + timeout_s
        while not condition():
            if time.monotonic() > deadline:
                state = {n: (self.current[n], round(self.steady_for(n), 2)) for n in self.current}
                raise SitlError(f"{what} not within {timeout_s:.0f} s (seq, steady s): {state}")
            time.sleep(0.005)


def fly_on_sitl(
    task_dir: Path,
    out_dir: Path,
    settings: SitlSettings | None = None,
    options: SitlFlightOptions | None = None,
) -> FlightRecord:
    """Fly the task in ``task_dir`` on three SITL instances; logs into ``out_dir``.

    Must run where SITL's ports are private (:mod:`missions.sitl.netns`).

    Raises
    ------
    SitlError
        If the simulators cannot be started, reached, readied, or kept at pace.
    FleetError
        If a vehicle refused a parameter, the upload, arming or the start.
    """
    settings = settings or SitlSettings()
    options = options or SitlFlightOptions()
    plan = FlightPlanFiles.read(task_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    policy = _policy(settings)
    names = [f"drone{k}" for k in (1, 2, 3)]
    with SitlGroup(settings, _homes(plan.missions), out_dir / "sitl") as instances:
        wall0, utc0 = time.monotonic(), time.time()
        clock = StretchedClock(settings.speedup, utc0, wall0)
        with Fleet.connect([i.address for i in instances], policy, names) as fleet:
            writers = [
                TlogWriter(link, out_dir / f"{link.name}.tlog", clock).start()
                for link in fleet.links
            ]
            try:
                return _fly(fleet, plan, settings, options, policy, clock, task_dir, writers)
            finally:
                for writer in writers:
                    writer.stop()


def _fly(
    fleet: Fleet,
    plan: FlightPlanFiles,
    settings: SitlSettings,
    options: SitlFlightOptions,
    policy: RetryPolicy,
    clock: StretchedClock,
    task_dir: Path,
    writers: Sequence[TlogWriter],
) -> FlightRecord:
    links = fleet.links
    sim = settings.speedup

    def streams(link: VehicleLink) -> None:
        for name in RECORDED_STREAMS:
            set_message_interval(link, name, 1.0 / options.stream_hz, policy)
        set_message_interval(link, "SYSTEM_TIME", SYSTEM_TIME_INTERVAL_S, policy)
        set_message_interval(link, "EKF_STATUS_REPORT", 0.5, policy)

    on_every_vehicle(links, "stream", streams)
    _wait_for(
        links,
        ("EKF_STATUS_REPORT",),
        lambda _, msg: (msg.flags & EKF_READY) == EKF_READY,
        settings.boot_timeout,
        "position estimate",
    )
    parameters = {}
    for k, link in enumerate(links):
        values = {**SITL_PARAMETERS, **plan.parameters[k]}
        if k < len(options.parameter_overrides):
            values.update(options.parameter_overrides[k])
        parameters[link.name] = values
    fleet.set_parameters([parameters[link.name] for link in links])
    # the upload reads the plan's parameters back, as it does for a ground station's user
    uploads = fleet.upload(plan.missions, parameters=plan.parameters)
    differences = tuple(str(error) for upload in uploads for error in upload.parameter_errors)
    holds = [m.items[plan.hold_seq] for m in plan.missions]
    progress = _Progress(links, holds, options.settle_speed, options.settle_distance)
    rates = _RateMeter(links)
    fleet.arm()
    fleet.start()
    # waits in wall time for the slowest pace accepted
    pace = sim * settings.min_rate
    # takeoff and settling take tens of simulated seconds: give them minutes
    airborne_s = 300.0 / pace + 30.0
    progress.wait(
        lambda: all(
            progress.current[n] == plan.hold_seq and progress.steady_for(n) >= options.settle_s
            for n in progress.current
        ),
        airborne_s,
        "every drone steady at its start hold",
    )
    report = _release(links, plan.release_seq, options.release_delays, sim, policy)
    flight_s = (2.0 * plan.duration_s + max(options.release_delays) + 30.0) / pace
    progress.wait(
        lambda: all(progress.current[link.name] == plan.end_seq[k] for k, link in enumerate(links)),
        flight_s,
        "every drone at its end hold",
    )
    end_boot = dict(progress.boot_s)
    progress.wait(
        lambda: all(progress.boot_s[n] >= end_boot[n] + options.end_margin_s for n in end_boot),
        options.end_margin_s / pace + 10.0,
        "the end margin",
    )
    achieved = rates.rates()
    slow = {n: r for n, r in achieved.items() if r < settings.min_rate * sim}
    if slow:
        raise SitlError(
            f"simulators ran slower than {settings.min_rate:.0%} of x{sim:g}: "
            + ", ".join(f"{n} x{r:.2f}" for n, r in slow.items())
        )
    vehicles = tuple(
        VehicleRecord(
            name=link.name,
            system_id=link.info.system_id,
            tlog=writers[k].path.name,
            rate=achieved[link.name],
            release_sent_s=clock.at(report.sent_s[k]),
            release_confirmed_s=clock.at(report.confirmed_s[k]),
        )
        for k, link in enumerate(links)
    )
    return FlightRecord(
        task_dir=str(task_dir),
        speedup=sim,
        hold_seq=plan.hold_seq,
        release_seq=plan.release_seq,
        end_seq=plan.end_seq,
        planned_duration_s=plan.duration_s,
        vehicles=vehicles,
        parameters=parameters,
        release_delays=options.release_delays,
        parameter_differences=differences,
    )
