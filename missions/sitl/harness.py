"""Fly a task on three ArduCopter SITL instances and record the flight.

The procedure is the one a ground station follows with real vehicles (README "Flying the
missions"), with the simulator's own additions marked:

1. start three simulators homed on the ground below each drone's start (seq 0 of its
   mission), their clocks from one epoch (``--start-time``) [SITL];
2. connect, ask for GLOBAL_POSITION_INT, MISSION_CURRENT, SYSTEM_TIME and, from SITL,
   SIM_STATE (the simulator's true position), and wait for every vehicle's estimate (a
   boot faster than the flight gets them at a rate its wall time can read, the flight at
   ``stream_hz``);
3. set the parameters of the plan (``drone{k}.parm``), each confirmed, plus ARMING_CHECK
   0 [SITL: no RC] (a test may set wrong ones on purpose);
4. upload each mission with read-back verification (``onboard``: the player's mission,
   and its trajectory by MAVLink FTP), and read the plan's parameters back;
5. on the ground, refuse the release if a vehicle's height source is not the plan's
   model's; otherwise arm and start all three (MISSION_START): they take off and hold;
6. once all three hover steadily at the hold (or, where wind keeps one from it, after
   ``hold_patience_s`` within the position-error model's bounds), check that they position
   themselves as the plan's position-error model assumes
   (:mod:`missions.execution.readiness`), and refuse the release otherwise; then bring
   the simulators' clocks together, as GNSS time is for real vehicles
   (:mod:`missions.sitl.clocks`) [SITL];
7. hand the flight to the executor of the mode (:mod:`missions.execution`): ``missions``
   releases the autopilots' own missions, ``stream`` flies the drones on targets from one
   clock, ``onboard`` releases their players; inject the planned faults
   (:mod:`missions.sitl.faults`) on cue; record until the plan's end, or a team stop and
   ``hold_after_stop_s``.

Everything the vehicles send is written to ``drone{k}.tlog`` (time base: the simulation's,
:class:`~missions.mavlink.tlog.StretchedClock`), what the ground did to ``flight.json`` and
an executor's clock and faults to ``execution.json``; :mod:`missions.flight_report` reads
them. Pace: the executors and the report work on the simulators' common clock, so a loaded
machine that slows the simulators changes nothing but the wall time; a flight slower than
``min_rate`` of the speed-up is refused (:class:`SitlError`).
"""

from __future__ import annotations

import json
import logging
import time
from collections.abc import Mapping, Sequence
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path
from typing import Any, Literal

from missions.autopilots.ardupilot import COPTER_MODES
from missions.execution.executor import Executor
from missions.execution.group_clock import RatePolicy
from missions.execution.missions import MissionsExecutor
from missions.execution.onboard import PLAYER_SCRIPT, OnboardExecutor
from missions.execution.options import ExecutionOptions
from missions.execution.readiness import Readiness, check_readiness, settings_reasons
from missions.execution.stream import StreamExecutor
from missions.execution.team import MonitorLimits
from missions.export.items import DroneMission
from missions.flight_report.record import (
    EXECUTION_FILE,
    FlightRecord,
    VehicleRecord,
    fresh_flight_directory,
)
from missions.mavlink.commands import set_message_interval
from missions.mavlink.errors import MavlinkError
from missions.mavlink.fleet import Fleet, on_every_vehicle
from missions.mavlink.guided import set_mode_message
from missions.mavlink.params import set_parameters
from missions.mavlink.policy import RetryPolicy
from missions.mavlink.tlog import StretchedClock, TlogWriter
from missions.mavlink.transport import VehicleLink
from missions.sitl.clocks import align_clocks
from missions.sitl.errors import SitlError
from missions.sitl.faults import FaultPlan, check_within
from missions.sitl.plan_files import FlightPlanFiles, Mode
from missions.sitl.process import SitlGroup, SitlHome
from missions.sitl.settings import SitlSettings
from missions.sitl.watch import HoldWatch, RateMeter, wait_for

logger = logging.getLogger(__name__)

#: Parameters the simulator needs and a real vehicle must not get from us.
SITL_PARAMETERS = {"ARMING_CHECK": 0.0}  # no RC, no pre-arm checks to pass
#: EKF_STATUS_REPORT flags of a usable position estimate: attitude, horizontal and vertical
#: velocity, absolute horizontal and vertical position.
EKF_READY = 1 | 2 | 4 | 16 | 32
#: Messages the flight report needs, besides what the vehicle sends unasked.
RECORDED_STREAMS = (
    "GLOBAL_POSITION_INT",
    "SIM_STATE",
    "MISSION_CURRENT",
    "POSITION_TARGET_LOCAL_NED",
)
#: The common clock and the pace: SYSTEM_TIME every this many simulated seconds.
SYSTEM_TIME_INTERVAL_S = 0.5


@dataclass(frozen=True)
class SitlFlightOptions:
    """How a SITL flight is flown and recorded (times in simulated seconds)."""

    mode: Mode = "missions"
    stream_hz: float = 50.0  #: recorded telemetry
    rate_hz: float = 20.0  #: the executor's ticks (stream: targets per second)
    #: targets ahead of each drone's present (horizontal, vertical) [s]; None: the mode's
    lead: tuple[float, float] | None = None
    settle_s: float = 3.0  #: steady hover at the hold before the release
    settle_speed: float = 0.05  #: [m/s] "steady": every drone slower than this
    #: [m] "steady": and every drone's estimate this close to its hold. Slow alone is not
    #: steady: a take-off closes its last centimetres of height slowly
    #: (:mod:`missions.autopilots.ardupilot`), and drones released merely slow start the
    #: mission below their hold (BENCHMARKS.md, "Home height"); horizontally too, which
    #: holds stock sensors at the start until their estimates converge (BENCHMARKS.md,
    #: "Settling at the hold")
    settle_distance: float = 0.02
    #: [s] at the hold without holding steady after which the hold is judged against the
    #: plan's position-error model instead (:meth:`HoldWatch.unsteady_reasons`): gusts keep
    #: a drone from ever holding within ``settle_distance``, a stock estimate converges for
    #: minutes
    hold_patience_s: float = 300.0
    end_margin_s: float = 3.0  #: recorded after the last drone reached its end
    hold_after_stop_s: float = 3.0  #: recorded after a team stop
    #: extra delay of each drone's release [s] (``missions``): a deliberately perturbed flight
    release_delays: tuple[float, float, float] = (0.0, 0.0, 0.0)
    #: parameters set on each vehicle after the plan's (a deliberately wrong setting)
    parameter_overrides: tuple[Mapping[str, float], ...] = field(default_factory=tuple)
    faults: tuple[FaultPlan, ...] = ()
    #: what the operator does after a team stop and ``hold_after_stop_s``: hold, or take
    #: the drones that left the execution's mode back and retreat along the plan to its
    #: start (stream and onboard)
    on_fault: Literal["hold", "retreat"] = "hold"
    check_readiness: bool = True  #: refuse the release when positioning is not the model's


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
        If the simulators cannot be started, reached (an instance that exited is named with
        its console's last lines), readied, or kept at pace.
    FleetError
        If a vehicle refused a parameter, the upload, arming or the start.
    InputError
        If a fault would strike at or after the plan's end (before anything starts).
    """
    settings = settings or SitlSettings()
    options = options or SitlFlightOptions()
    task_dir, out_dir = task_dir.resolve(), out_dir.resolve()
    plan = FlightPlanFiles.read(task_dir, options.mode)
    check_within(options.faults, plan.flown_duration(options.mode))
    fresh_flight_directory(out_dir)
    policy = _policy(settings)
    names = [f"drone{k}" for k in (1, 2, 3)]
    scripts = (PLAYER_SCRIPT,) if options.mode == "onboard" else ()
    boot = settings.model_copy(update={"speedup": settings.boot_speedup or settings.speedup})
    group = SitlGroup(boot, _homes(plan.missions), out_dir / "sitl", scripts=scripts)
    with group as instances:
        wall0, utc0 = time.monotonic(), time.time()
        clock = StretchedClock(boot.speedup, utc0, wall0)
        try:
            fleet = Fleet.connect([i.address for i in instances], policy, names)
        except MavlinkError:
            group.check_running()  # a simulator that exited says why
            raise
        with fleet:
            writers = [
                TlogWriter(link, out_dir / f"{link.name}.tlog", clock).start()
                for link in fleet.links
            ]
            try:
                return _fly(fleet, plan, settings, options, policy, clock, task_dir, out_dir)
            finally:
                for writer in writers:
                    writer.stop()


def _executor(
    mode: Mode, links: Sequence[VehicleLink], plan: FlightPlanFiles, options: SitlFlightOptions,
    speedup: float, policy: RetryPolicy, start_seq: int,
) -> Executor:  # fmt: skip
    """The executor of ``mode``, its tolerances from the task's position-error model: the
    plan's clearance is what a drone's error may spend."""
    clearance = plan.model.obstacle_clearance
    execution = ExecutionOptions(
        rate_hz=options.rate_hz,
        lead=options.lead,
        policy=RatePolicy(tracking_tolerance=clearance, formation_tolerance=clearance),
        limits=MonitorLimits(stray_distance=2 * clearance, min_fix_type=plan.model.min_fix_type),
    )
    common = dict(options=execution, speedup=speedup, retry=policy)
    if mode == "stream":
        return StreamExecutor(links, plan.trajectory, plan.origin, room=plan.room, **common)  # type: ignore[arg-type]
    if mode == "onboard":
        return OnboardExecutor(links, plan.trajectory, plan.origin, player_seq=start_seq,
                               **common)  # type: ignore[arg-type]  # fmt: skip
    return MissionsExecutor(links, plan.trajectory, plan.origin, release_seq=start_seq,
                            **common)  # type: ignore[arg-type]  # fmt: skip


def _fly(
    fleet: Fleet, plan: FlightPlanFiles, settings: SitlSettings, options: SitlFlightOptions,
    policy: RetryPolicy, clock: StretchedClock, task_dir: Path, out_dir: Path,
) -> FlightRecord:  # fmt: skip
    links = fleet.links
    sim = settings.speedup
    # through the boot, no more messages per wall second than the flight's pace will bring
    _record(links, options.stream_hz * min(1.0, sim / clock.speedup), policy)
    wait_for(
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
    missions, start_seq = plan.for_mode(options.mode)
    # the upload reads the plan's parameters back, as it does for a ground station's user
    uploads = fleet.upload(missions, parameters=plan.parameters)
    differences = tuple(str(error) for upload in uploads for error in upload.parameter_errors)
    executor = _executor(options.mode, links, plan, options, sim, policy, start_seq)
    # waits in wall time are sized for the slowest pace
    pace = min(sim, clock.speedup) * settings.min_rate
    if isinstance(executor, OnboardExecutor):
        executor.upload(timeout=60.0)
    holds = [m.items[plan.hold_seq] for m in missions]
    watch = HoldWatch(links, holds, options.settle_speed, options.settle_distance, options.settle_s)
    rates = RateMeter(links)
    check = options.check_readiness
    readiness = Readiness(settings_reasons(links, plan.model, policy) if check else ())
    if readiness.ready:
        readiness = _take_off(fleet, watch, plan, options, policy, pace)
    injected: list[dict] = []
    leads: tuple[dict[str, float], ...] = ()
    if readiness.ready:
        if clock.speedup != sim:
            _change_pace(fleet, sim, clock, rates)
        _record(links, options.stream_hz, policy)  # the readiness check asked for less
        aligned = align_clocks(links, sim, policy)
        for vehicle in executor.vehicles:
            vehicle.forget_clock_before(aligned.settled_at)
        leads = (aligned.before, aligned.after)
        injected = _execute(executor, plan, options, policy, pace)
        record = executor.record.as_dict() if executor.record else {}
        (out_dir / EXECUTION_FILE).write_text(json.dumps(record, indent=2) + "\n", encoding="utf-8")
    else:
        logger.warning("release refused: %s", "; ".join(readiness.reasons))
    _wait_margin(watch, options.end_margin_s, pace)
    achieved = rates.rates()
    paced = clock.speedup  # the flight's, or the boot's where the release was refused
    slow = {n: r for n, r in achieved.items() if r < settings.min_rate * paced}
    if slow:
        raise SitlError(
            f"simulators ran slower than {settings.min_rate:.0%} of x{paced:g}: "
            + ", ".join(f"{n} x{r:.2f}" for n, r in slow.items())
        )
    report = executor.report if isinstance(executor, MissionsExecutor) else None
    vehicles = tuple(
        VehicleRecord(
            name=link.name,
            system_id=link.info.system_id,
            tlog=f"{link.name}.tlog",
            rate=achieved[link.name],
            release_sent_s=clock.at(report.sent_s[k]) if report else 0.0,
            release_confirmed_s=clock.at(report.confirmed_s[k]) if report else 0.0,
            clock_lead_s=tuple(lead.get(link.name, 0.0) for lead in leads),
        )
        for k, link in enumerate(links)
    )
    return FlightRecord(
        task_dir=str(task_dir),
        speedup=sim,
        hold_seq=plan.hold_seq,
        release_seq=start_seq,
        end_seq=tuple(m.items[-1].seq for m in missions),
        planned_duration_s=plan.duration_s,
        vehicles=vehicles,
        parameters=parameters,
        release_delays=options.release_delays,
        parameter_differences=differences,
        mode=options.mode,
        refused=tuple(readiness.reasons),
        faults=tuple(injected),
    )


def _record(links: Sequence[VehicleLink], hz: float, policy: RetryPolicy) -> None:
    """Ask every vehicle for :data:`RECORDED_STREAMS` at ``hz`` [per simulated second],
    the clock and the estimate's status at their own rates."""

    def streams(link: VehicleLink) -> None:
        for name in RECORDED_STREAMS:
            set_message_interval(link, name, 1.0 / hz, policy)
        set_message_interval(link, "SYSTEM_TIME", SYSTEM_TIME_INTERVAL_S, policy)
        set_message_interval(link, "EKF_STATUS_REPORT", 0.1, policy)

    on_every_vehicle(links, "stream", streams)


def _change_pace(fleet: Fleet, speedup: float, clock: StretchedClock, rates: RateMeter) -> None:
    """The simulators' pace from now on: ``speedup`` (SIM_SPEEDUP, set on the three at once
    and each confirmed), and the log's clock and the pace's measure with them."""
    now = time.monotonic()
    fleet.set_parameters([{"SIM_SPEEDUP": speedup}] * len(fleet.links))
    clock.change_pace(speedup, (now + time.monotonic()) / 2)
    rates.restart()


def _take_off(
    fleet: Fleet,
    watch: HoldWatch,
    plan: FlightPlanFiles,
    options: SitlFlightOptions,
    policy: RetryPolicy,
    pace: float,
) -> Readiness:
    """Arm and start the three, wait until they hold steady at the start, and check them
    there (step 6)."""
    fleet.arm()
    fleet.start()
    # takeoff and settling take tens of simulated seconds: give them minutes
    watch.wait(
        lambda: all(
            watch.current[n] == plan.hold_seq
            and (
                watch.steady_for(n) >= options.settle_s
                or watch.at_current_for(n) >= options.hold_patience_s
            )
            for n in watch.current
        ),
        300.0 / pace + options.hold_patience_s / pace + 30.0,
        "every drone steady at its start hold",
    )
    readiness = Readiness(
        watch.unsteady_reasons(plan.model, options.hold_patience_s, options.settle_s)
    )
    if not options.check_readiness:
        return readiness
    checked = check_readiness(
        fleet.links, plan.model, plan.trajectory.in_task_frame(plan.trajectory.position[0]),
        plan.origin, plan.home_height, policy,
    )  # fmt: skip
    return replace(checked, reasons=readiness.reasons + checked.reasons)


def _execute(
    executor: Executor,
    plan: FlightPlanFiles,
    options: SitlFlightOptions,
    policy: RetryPolicy,
    pace: float,
) -> list[dict]:
    """Play the plan with ``executor``, injecting ``options.faults`` on cue; until the
    plan's end, or a team stop and ``hold_after_stop_s``."""
    executor.prepare(timeout=60.0)
    if isinstance(executor, MissionsExecutor):
        executor.engage(30.0, options.release_delays)
    else:
        executor.engage(30.0)
    for fault in options.faults:
        if fault.kind == "late":
            executor.hold_back(fault.drone, fault.value)
    record = executor.start()
    duration = plan.flown_duration(options.mode)
    pending = sorted((f for f in options.faults if f.kind != "late"), key=lambda f: f.at)
    injected: list[dict] = [asdict(f) | {"time": record.start} for f in options.faults
                            if f.kind == "late"]  # fmt: skip
    deadline = time.monotonic() + (2.0 * duration + 60.0) / pace
    stopped_at: float | None = None
    retreating = False
    while time.monotonic() < deadline:
        now = executor.present()
        elapsed = now - record.start
        while pending and elapsed >= pending[0].at:
            fault = pending.pop(0)
            # its time is when it was sent: a parameter's confirmation comes after it acts
            struck = executor.present()
            injected.append(_inject(fault, executor, policy) | {"time": struck})
        if executor.stopped:
            stopped_at = stopped_at or now
            if now - stopped_at >= options.hold_after_stop_s + 1.0:
                if options.on_fault == "retreat" and not retreating:
                    retreating = _retreat(executor, injected, pace)
                    if retreating:
                        continue
                break
        elif retreating:
            if executor.at_start:
                break
        elif _finished(executor, plan, now, record.start, duration):
            break
        time.sleep(0.01)
    else:
        raise SitlError(f"{executor.mode} flight did not end within {2.0 * duration + 60.0:.0f} s")
    executor.stop()
    return injected


def _inject(fault: FaultPlan, executor: Executor, policy: RetryPolicy) -> dict[str, Any]:
    """Make ``fault`` happen now; returns what was done (for the flight record)."""
    k = fault.drone - 1
    link = executor.links[k]
    done: dict[str, Any] = asdict(fault)
    if fault.kind == "gps":
        set_parameters(link, {"SIM_GPS_DISABLE": 1.0}, policy)
    elif fault.kind == "link":
        link.mute()
        executor.lose_link(fault.drone)
    elif fault.kind == "mode":
        link.send(set_mode_message(COPTER_MODES["BRAKE"], link.target))
    elif fault.kind == "motor":
        # SIM_ENGINE_FAIL counts the motors from 0
        set_parameters(
            link, {"SIM_ENGINE_FAIL": float(fault.motor - 1), "SIM_ENGINE_MUL": fault.value}, policy
        )
    return done


def _retreat(executor: Executor, injected: list[dict], pace: float) -> bool:
    """The operator's retreat after a team stop: take back the drones whose mode was
    switched, then fly the plan backwards to its start; False if the team cannot (a fault
    remains), which is recorded."""
    if isinstance(executor, MissionsExecutor):
        return False
    for fault in injected:
        if fault["kind"] == "mode":
            executor.restore_mode(fault["drone"])
    deadline = time.monotonic() + 10.0 / pace
    while True:
        try:
            executor.retreat()
        except RuntimeError as error:
            if time.monotonic() < deadline:
                time.sleep(0.05)
                continue
            logger.warning("no retreat: %s", error)
            injected.append({"kind": "operator", "action": "hold", "reason": str(error)})
            return False
        injected.append({"kind": "operator", "action": "retreat", "time": executor.present()})
        return True


def _finished(
    executor: Executor, plan: FlightPlanFiles, now: float, start: float, duration: float
) -> bool:
    """Whether the plan is over: its clock at the end (stream, onboard), or every drone in
    its last item (missions)."""
    if isinstance(executor, MissionsExecutor):
        return now - start > 0.0 and all(
            v.mission_seq == plan.end_seq[k] for k, v in enumerate(executor.vehicles)
        )
    return executor.wait(0.0)


def _wait_margin(watch: HoldWatch, margin: float, pace: float) -> None:
    """``margin`` of simulated time more, recorded."""
    end_boot = dict(watch.boot_s)
    watch.wait(
        lambda: all(watch.boot_s[n] >= end_boot[n] + margin for n in end_boot),
        margin / pace + 10.0,
        "the end margin",
    )
