"""Replay: three mock ArduCopters fly the Rescue task's missions over MAVLink, and the load
they carry stays feasible, collision-free and on the planned path.

The task is planned and exported by :func:`run_task` (what ``flycrane plan`` and the
service run); the three ``drone{k}.mission.json`` files are uploaded with :class:`Fleet` to
three :class:`MockAutopilot` homed on the ground below each drone's start (seq 0), after
each drone's ``drone{k}.parm`` was set on it, as the README's procedure says: one
MISSION_START takes them off to their hold, and one release (MISSION_SET_CURRENT to the
summary's ``release_seq``) sends them on together. Everything the checks use comes back
over MAVLink: GLOBAL_POSITION_INT (position, velocity, ``time_boot_ms``), MISSION_CURRENT
and MISSION_ITEM_REACHED. The platform is rebuilt from the three drones' positions alone
(direct kinematics) and judged by the task's own validity checker on the real obstacles
(the set-down's landing surfaces excepted once it has begun), so the evidence does not go
through the mission builder's geometry. The mock flies spline legs with the model the plan
was timed with; ``tests/missions/mavlink/test_mock_vs_sitl.py`` holds that model to SITL.

Simulated time: the mocks share one :class:`SimClock` at :data:`SPEEDUP`. ``time_boot_ms``
counts simulated milliseconds from the shared epoch, so the three streams compare directly.
A speed-up also multiplies the wall-clock latency of the release (a 15 ms scheduling hiccup
on a busy core is 0.15 s simulated, more than this plan tolerates); a real link delivers it
within a millisecond. So the clock is held still while the release goes out
(``SimClock.held``): the three vehicles leave at one simulated instant, and offsets happen
only where a test imposes them (a release deliberately late: ``SimClock.held(at=...)``).
The mocks step in lock step on that clock, so a loaded machine slows the simulation down
instead of moving the drones apart. The slow soak variant flies at x1 without the hold.
"""

from __future__ import annotations

import json
import re
import time
from collections.abc import Callable, Sequence
from contextlib import ExitStack
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest
from numpy.typing import NDArray
from scipy.integrate import cumulative_trapezoid
from scipy.signal import savgol_filter

from flycrane.model.direct_kinematics import (
    DirectKinematicsResult,
    configuration_from_drone_positions,
)
from flycrane.model.kinematics import drone_positions_from_configuration
from flycrane.planning.planners import PlannerOptions
from flycrane.planning.validity import ValidityChecker
from missions.export.formats import mission_from_json
from missions.export.items import DroneMission, MavCmd
from missions.export.parameter_file import read_parameter_file
from missions.geodesy import DEGREE_UNIT, enu_from_geodetic
from missions.mavlink.commands import release
from missions.mavlink.fleet import Fleet
from missions.mavlink.policy import RetryPolicy
from missions.mavlink.telemetry import SeqEvent, VehicleTelemetry
from missions.mavlink.tlog import TlogWriter
from missions.mock.autopilot import MockAutopilot, MockConfig
from missions.mock.config import Imperfections
from missions.mock.kinematic_flight import Geodetic
from missions.mock.sim_clock import SimClock
from missions.task.pipeline import run_task
from missions.task.resolve import ResolvedTask, resolve_task
from missions.task.spec import TaskSpec
from missions.trajectory.tracks import Track
from missions.trajectory.waypoints import planned_configurations
from tests.missions.loopback import free_udp_port, no_leaked_threads  # noqa: F401 (autouse fixture)

SPEEDUP = 10.0
#: GLOBAL_POSITION_INT at every step of the mocks (the clock's step, 0.02 s): the most samples
#: for the noise test, and one per step times MISSION_ITEM_REACHED to a step.
STREAM_HZ = 50.0
STEP_S = 1.0 / STREAM_HZ
#: Start synchronisation seen in the telemetry [s]: the mocks' step grids differ in phase
#: (less than a step), and an event is reported at the end of the step it happened in.
SYNC_S = 2 * STEP_S
POLICY = RetryPolicy(request_timeout_s=0.25, retries=4, deadline_s=20.0,
                     no_space_backoff_s=0.1, no_space_retry_s=5.0, heartbeat_timeout_s=3.0,
                     gcs_heartbeat_interval_s=0.1)  # fmt: skip

#: Leg arrival times of the three drones agree within this [s], and each is within it of
#: the plan: a third of what the plans tolerate (0.28 s). The mock plays the modelled legs
#: back on its 20 ms step and reports events at the end of their step; measured on Rescue
#: and Puzzle: arrivals within 0.09 s of the plan, spreads within 0.06 s.
ARRIVAL_SPREAD_S = 0.1
#: Reconstructed platform point P against the planned P at the same progress [m]: what
#: the plan says its modelled vehicles do (``max_tracking_deviation`` in summary.json: the
#: targets within max_platform_deviation, 0.03, and each vehicle's lag behind its own),
#: plus MAVLink's 1e-7 degree coordinates, 0.011, and progress matched to the nearest
#: dense sample of the plan, 0.01.
RESOLUTION_M = 0.021
#: Noise handling (the imperfect flights): positions fused with the noise-free reported
#: velocity, the position offset fitted as a local line over this window [s]
#: (:func:`fused_positions`).
FUSION_WINDOW_S = 4.0


# --- the exported task ---------------------------------------------------------------


@dataclass(frozen=True)
class Exported:
    """What run_task wrote, read back as a user of the files would."""

    resolved: ResolvedTask
    missions: tuple[DroneMission, ...]
    parameters: tuple[dict[str, float], ...]  #: drone{k}.parm
    track: Track  #: the dense planned track (time law, configurations, drone positions)
    waypoint_time: NDArray[np.float64]  #: (K,) planned times of the timed waypoints [s]
    tolerance: dict  #: timing_tolerance(...) as tracks.json reports it
    hold_seq: int  #: the hold after take-off
    release_seq: int  #: the first timed leg, the release's MISSION_SET_CURRENT
    set_down: dict | None  #: tracks.json's set-down leg (start_time, surfaces)
    directory: Path  #: the task's directory
    tracking_deviation: float  #: summary.json's max_tracking_deviation [m]
    #: summary.json's early legs: (drone, leg), 1-based, which ArduCopter's speed floor
    #: makes that drone fly faster than planned (the plan's check models them so)
    early_legs: tuple[tuple[int, int], ...] = ()


@pytest.fixture(scope="module")
def rescue(tmp_path_factory: pytest.TempPathFactory) -> Exported:
    return export(TaskSpec(planner=PlannerOptions(seed=0, time_budget=60)), tmp_path_factory)


@pytest.fixture(scope="module")
def puzzle(tmp_path_factory: pytest.TempPathFactory) -> Exported:
    # seed 2: T-RRT solved it in 2.3 s in the 100-seed Table I run (BENCHMARKS.md)
    task = TaskSpec(scene="puzzle", planner=PlannerOptions(seed=2, time_budget=60))
    return export(task, tmp_path_factory)


def export(task: TaskSpec, tmp_path_factory: pytest.TempPathFactory) -> Exported:
    """Run the task as the service would and read its files back."""
    resolved = resolve_task(task)
    out = tmp_path_factory.mktemp(str(task.scene))
    outcome = run_task(task, out, resolved=resolved)
    assert outcome.status == "done", outcome.reason
    missions = tuple(
        mission_from_json(json.loads((out / f"drone{k}.mission.json").read_text()))
        for k in (1, 2, 3)
    )
    tracks = json.loads((out / "tracks.json").read_text())
    q = np.array(tracks["dense"]["configurations"])
    track = Track(np.array(tracks["dense"]["time"]), q,
                  drone_positions_from_configuration(resolved.problem.system, q))  # fmt: skip
    assert tracks["timing_tolerance"] == outcome.mission.timing_tolerance.as_dict()
    summary = json.loads((out / "summary.json").read_text())["mission"]
    return Exported(
        resolved, missions,
        tuple(read_parameter_file(out / f"drone{k}.parm") for k in (1, 2, 3)),
        track, np.array(tracks["time"]), tracks["timing_tolerance"],
        summary["release"]["hold_seq"], summary["release"]["release_seq"],
        tracks.get("set_down"), out, summary["max_tracking_deviation"],
        tuple((int(d), int(leg)) for d, leg in summary["early_legs"]),
    )  # fmt: skip


def home_below_start(mission: DroneMission) -> Geodetic:
    """Seq 0: the ground point below the drone's start, altitude AMSL (frame GLOBAL_INT)."""
    home = mission.items[0]
    return Geodetic(home.x * DEGREE_UNIT, home.y * DEGREE_UNIT, home.z)


def timed_legs(mission: DroneMission) -> list[int]:
    """Seqs of the timed legs: the spline waypoints after the release."""
    return [i.seq for i in mission.items if i.command == MavCmd.NAV_SPLINE_WAYPOINT]


# --- flying ---------------------------------------------------------------------------


@dataclass(frozen=True)
class Flight:
    telemetry: tuple[VehicleTelemetry, ...]  #: drone 1..3
    wall_s: float  #: from the release to the last leg's end, wall clock [s]


def fly(
    exported: Exported,
    imperfections: Sequence[Imperfections],
    speedup: float = SPEEDUP,
    hold_clock: bool = True,
    release_delays: Sequence[float] = (0.0, 0.0, 0.0),
    tlog_dir: Path | None = None,
) -> Flight:
    """Three mocks on loopback, one shared clock: parameters, upload, stream, arm, one
    MISSION_START; once all three hold, one release (drone k ``release_delays[k]`` later
    [simulated s], a deliberately perturbed flight); record until every drone reports its
    last timed leg reached. With ``tlog_dir``, also a tlog per drone there
    (``drone{k}.tlog``, timed by the simulated clock), two simulated seconds longer."""
    clock = SimClock(speedup=speedup)
    mocks: list[MockAutopilot] = []
    addresses, names = [], []
    try:
        for k, (mission, imperfect) in enumerate(zip(exported.missions, imperfections,
                                                     strict=True)):  # fmt: skip
            port = free_udp_port()
            config = MockConfig(system_id=k + 1, home=home_below_start(mission),
                                imperfections=imperfect)  # fmt: skip
            mocks.append(MockAutopilot(f"udpin:127.0.0.1:{port}", config, clock).start())
            addresses.append(f"udpout:127.0.0.1:{port}")
            names.append(f"drone{k + 1}")
        last = {name: timed_legs(m)[-1]
                for name, m in zip(names, exported.missions, strict=True)}  # fmt: skip
        with Fleet.connect(addresses, POLICY, names) as fleet, ExitStack() as logs:
            if tlog_dir is not None:
                simulated_utc = lambda: clock.epoch_utc + clock.now()  # noqa: E731
                for link, name in zip(fleet.links, names, strict=True):
                    logs.enter_context(TlogWriter(link, tlog_dir / f"{name}.tlog", simulated_utc))
            fleet.set_parameters(exported.parameters)
            uploads = fleet.upload(exported.missions, parameters=exported.parameters)
            assert not [e for u in uploads for e in u.parameter_errors]
            with fleet.recorder() as recorder:
                fleet.request_position_streams(rate_hz=STREAM_HZ)
                fleet.arm()
                fleet.start()
                # the take-off is a few seconds: 30 s simulated is never reached
                wait_until(lambda: all(holding(vehicle, exported.hold_seq)
                                       for vehicle in recorder.snapshot().values()),
                           30.0 / speedup + 5.0, "the drones did not reach their hold")  # fmt: skip
                started = time.monotonic()
                if hold_clock:
                    release_at = clock.now() + STEP_S
                    for delay in sorted(set(release_delays)):
                        group = [link for link, d in zip(fleet.links, release_delays,
                                                         strict=True) if d == delay]  # fmt: skip
                        with clock.held(at=release_at + delay):
                            release(group, exported.release_seq, POLICY)
                else:
                    assert not any(release_delays), "delays need the held clock"
                    fleet.release(exported.release_seq)
                # the plan's duration and the imperfections: 1.5 x that plus 10 s is never
                # reached
                simulated = 1.5 * float(exported.waypoint_time[-1]) + 10.0
                wait_until(lambda: all(finished(vehicle, last[name])
                                       for name, vehicle in recorder.snapshot().items()),
                           simulated / speedup + 5.0, "the drones did not finish")  # fmt: skip
                wall_s = time.monotonic() - started
                telemetry = recorder.snapshot()
                if tlog_dir is not None:  # the report judges a margin after the end
                    end = clock.now() + 2.0
                    wait_until(lambda: clock.now() >= end, 2.0 / speedup + 5.0, "the margin")
    finally:
        for mock in mocks:
            mock.stop()
    return Flight(tuple(telemetry[name] for name in names), wall_s)


def wait_until(condition: Callable[[], bool], timeout_s: float, failure: str) -> None:
    deadline = time.monotonic() + timeout_s
    while not condition():
        assert time.monotonic() < deadline, failure
        time.sleep(0.05)


def holding(vehicle: VehicleTelemetry, hold_seq: int) -> bool:
    """The hold after take-off is the current item."""
    return bool(vehicle.current) and vehicle.current[-1].seq == hold_seq


def finished(vehicle: VehicleTelemetry, seq: int) -> bool:
    """Item ``seq`` reached, and a position received after it (which times the event)."""
    reached = [e.received_s for e in vehicle.reached if e.seq == seq]
    return bool(reached) and vehicle.positions[-1].received_s > reached[0]


# --- what the telemetry says ------------------------------------------------------------


@dataclass(frozen=True)
class RecordedTrack:
    """One drone's recorded track in the task's ENU frame, simulated time."""

    time: NDArray[np.float64]  #: (N,) [s]
    enu: NDArray[np.float64]  #: (N, 3) [m]
    velocity: NDArray[np.float64]  #: (N, 3) ENU [m/s]
    reached: dict[int, float]  #: seq -> simulated time of its MISSION_ITEM_REACHED [s]
    current: dict[int, float]  #: seq -> simulated time it first became current [s]


def recorded_track(vehicle: VehicleTelemetry, exported: Exported) -> RecordedTrack:
    origin = exported.resolved.task.mission.origin
    positions = vehicle.positions
    t = np.array([p.time_boot_ms for p in positions]) / 1000.0
    enu = enu_from_geodetic(
        np.array([p.lat_e7 for p in positions]) * DEGREE_UNIT,
        np.array([p.lon_e7 for p in positions]) * DEGREE_UNIT,
        np.array([p.alt_mm for p in positions]) / 1000.0,  # AMSL, as the origin's altitude
        origin,
    )
    north, east, down = np.array([p.velocity_ned_cms for p in positions]).T / 100.0
    # MISSION_ITEM_REACHED and MISSION_CURRENT have no timestamp. The mock sends a step's
    # events before that step's GLOBAL_POSITION_INT, over one socket read by one thread, so
    # the first position received after the event carries the event's step time (to one
    # step, 0.02 s).
    received = np.array([p.received_s for p in positions])

    def timed(events: Sequence[SeqEvent]) -> dict[int, float]:
        first: dict[int, float] = {}
        for event in events:
            k = int(np.searchsorted(received, event.received_s, side="right"))
            if k < len(t):
                first.setdefault(event.seq, float(t[k]))
        return first

    velocity = np.column_stack([east, north, -down])
    return RecordedTrack(t, enu, velocity, timed(vehicle.reached), timed(vehicle.current))


def fused_positions(track: RecordedTrack) -> NDArray[np.float64]:
    """Positions with the reported noise averaged out, keeping the motion.

    The mock adds its noise to the reported position only; the reported velocity is the
    state's (rounded to 1 cm/s). So the velocity, integrated, gives the motion, and the
    noisy positions only the offset of that integral, which drifts slowly (velocity rounding:
    at most 0.5 cm/s). The offset is fitted as a local line over FUSION_WINDOW_S: 200
    samples of 5 cm noise leave about 0.4 cm (at most 2 cm, in a kinematic replay of this
    flight with six noise seeds). Smoothing the positions alone over 0.5 to 1 s left
    errors of 4 to 6 cm at the speed changes and, on some seeds, false collisions: the
    bridge clears the roofs and the ground by 2.5 to 5 cm in this task.
    """
    integral = cumulative_trapezoid(track.velocity, track.time, axis=0, initial=0.0)
    window = round(FUSION_WINDOW_S / STEP_S) | 1
    offset = savgol_filter(track.enu - integral, window, polyorder=1, axis=0)
    return integral + offset


@dataclass(frozen=True)
class Replay:
    """The three drones on common times over the planned part of the flight."""

    time: NDArray[np.float64]  #: (N,) simulated [s]
    drones: NDArray[np.float64]  #: (N, 3, 3) ENU [m]
    leave: NDArray[np.float64]  #: (3,) when each drone was released from its hold [s]
    arrivals: NDArray[np.float64]  #: (3, K - 1) when each reached each timed leg's end [s]


def replay(exported: Exported, flight: Flight, fuse: bool = False) -> Replay:
    """Align the drones on common times (linear interpolation; the mocks step on their own
    grids) from the first drone's release to the last reaching its last leg's end."""
    tracks = [recorded_track(v, exported) for v in flight.telemetry]
    leave, arrivals = [], []
    for track, mission in zip(tracks, exported.missions, strict=True):
        timed = timed_legs(mission)
        assert len(timed) == len(exported.waypoint_time) - 1
        leave.append(track.current[exported.release_seq])
        arrivals.append([track.reached[seq] for seq in timed])
    t = np.arange(min(leave), max(a[-1] for a in arrivals) + STEP_S / 2, STEP_S)
    drones = np.stack([
        np.column_stack([np.interp(t, track.time, p[:, axis]) for axis in range(3)])
        for track in tracks
        for p in [fused_positions(track) if fuse else track.enu]
    ], axis=1)  # fmt: skip
    return Replay(t, drones, np.array(leave), np.array(arrivals))


def rebuild(exported: Exported, flown: Replay) -> DirectKinematicsResult:
    """The platform configuration at every sample, from the drones' positions only; the
    Newton iteration starts from the planned configuration at the same mission time."""
    mission_time = np.clip(flown.time - flown.time[0], 0.0, exported.track.duration)
    initial = planned_configurations(exported.track, mission_time)
    return configuration_from_drone_positions(
        exported.resolved.problem.system, flown.drones, initial=initial
    )


def deviation_at_same_progress(track: Track, drones: NDArray, q: NDArray) -> NDArray:
    """|P_rebuilt - P_planned| [m] where the plan's progress is the dense sample whose three
    drone positions are nearest the flown ones (so delays common to all drones and the
    stretch of the whole track do not count; what differs between the drones does)."""
    flown, planned = drones.reshape(len(drones), 9), track.drones.reshape(len(track.time), 9)
    squared = (flown**2).sum(1)[:, None] + (planned**2).sum(1)[None] - 2.0 * flown @ planned.T
    nearest = np.argmin(squared, axis=1)
    return np.linalg.norm(q[:, :3] - track.q[nearest, :3], axis=1)


def real_obstacles(exported: Exported, mission_time: float) -> ValidityChecker:
    """The task's validity on the obstacles as they are (no planning clearance): what a
    flown load must not touch; once the set-down has begun, its landing surfaces are the
    intended contact."""
    validity = exported.resolved.problem.validity.with_clearance(0.0)
    set_down = exported.set_down
    if set_down is not None and mission_time >= set_down["start_time"]:
        return validity.without(tuple(set_down["surfaces"]))
    return validity


def judge(exported: Exported, flown: Replay, q: NDArray) -> tuple[NDArray[np.bool_], str]:
    """Which rebuilt samples are safe, and a report of the first unsafe one."""
    mission_time = flown.time - flown.leave.min()
    safe = np.ones(len(q), dtype=bool)
    cut = np.inf if exported.set_down is None else exported.set_down["start_time"]
    for part in (mission_time < cut, mission_time >= cut):
        if part.any():
            validity = real_obstacles(exported, float(mission_time[part][0]))
            safe[part] = validity.is_safe(q[part])
    bad = np.flatnonzero(~safe)
    if not len(bad):
        return safe, "all safe"
    first = bad[0]
    validity = real_obstacles(exported, float(mission_time[first]))
    when = mission_time[first]
    return safe, (f"{len(bad)} of {len(safe)} samples unsafe, first at {when:.2f} s of the "
                  f"plan: {validity.explain(q[first])}")  # fmt: skip


# --- the tests --------------------------------------------------------------------------


def check_ideal_flight(exported: Exported, flight: Flight) -> None:
    flown = replay(exported, flight)
    rebuilt = rebuild(exported, flown)
    assert rebuilt.converged.all(), f"{(~rebuilt.converged).sum()} samples did not converge"
    safe, report = judge(exported, flown, rebuilt.q)
    assert safe.all(), report

    # the three left their hold together (one release, clock held)...
    assert np.ptp(flown.leave) <= SYNC_S
    # ...and reach every waypoint together, and when the plan says, but at the end of a
    # leg the plan says a drone flies early, where that drone is never late
    late = flown.arrivals - flown.leave[:, None] - exported.waypoint_time[None, 1:]
    timed = np.ones(late.shape[1], dtype=bool)
    for drone, leg in exported.early_legs:
        timed[leg - 1] = False
        assert late[drone - 1, leg - 1] <= ARRIVAL_SPREAD_S, f"drone {drone} late, leg {leg}"
    spread = np.ptp(flown.arrivals[:, timed], axis=0)
    assert spread.max() <= ARRIVAL_SPREAD_S, f"arrival spreads {np.round(spread, 3)}"
    assert np.abs(late[:, timed]).max() <= ARRIVAL_SPREAD_S, f"arrivals - plan {np.round(late, 3)}"

    deviation = deviation_at_same_progress(exported.track, flown.drones, rebuilt.q)
    allowed = exported.tracking_deviation + RESOLUTION_M
    assert deviation.max() <= allowed, f"P off the plan by {deviation.max():.3f} m"


def test_ideal_flight_keeps_the_load_safe_and_on_the_plan(rescue: Exported):
    flight = fly(rescue, [Imperfections()] * 3)
    check_ideal_flight(rescue, flight)


def test_ideal_flight_threads_the_puzzle_piece_through_the_hole(puzzle: Exported):
    """The narrow passage: the flown load clears the slab all the way, and ends below it."""
    flight = fly(puzzle, [Imperfections()] * 3)
    check_ideal_flight(puzzle, flight)
    flown = rebuild(puzzle, replay(puzzle, flight)).q
    assert flown[:, 4].max() > 0.1  # threaded at a tilt
    assert flown[-1, 2] < 4.6  # platform 0.4 m above the slab: both bars below it


@pytest.mark.slow
def test_ideal_flight_in_real_time_without_holding_the_clock(rescue: Exported):
    """Soak: the same flight at x1 (35 s), started as a ground station would, unaided."""
    flight = fly(rescue, [Imperfections()] * 3, speedup=1.0, hold_clock=False)
    check_ideal_flight(rescue, flight)


def late_drones(case: str) -> set[int]:
    """Drone indices (0-based) of the tolerance's worst case, "drones 1 and 3 late"."""
    found = {int(d) - 1 for d in re.findall(r"\d+", case)}
    assert found and found <= {0, 1, 2}, case
    return found


@pytest.mark.parametrize("factor", [1 / 3, 2.5], ids=["within-tolerance", "beyond-tolerance"])
def test_imperfect_flight_is_safe_exactly_when_the_timing_tolerance_says(
    rescue: Exported, factor: float
):
    """Late releases on the tolerance's worst case, a 2 % slower fleet and 5 cm noise.

    ``timing_tolerance`` says in advance how late a release the mission survives (the
    worst of the six cases of one or two drones late). Flown with a release offset below
    it, no reconstructed sample may be unsafe; above it, unsafe samples must appear.
    The same speed scale on all three (vehicles of one type and tuning): different ones
    are a speed mismatch, the tolerance's other figure.
    """
    tolerance = rescue.tolerance["start_offset"]
    late = late_drones(rescue.tolerance["start_offset_case"])
    offset = factor * tolerance
    delays = [offset if k in late else 0.0 for k in range(3)]
    imperfections = [Imperfections(speed_scale=0.98, position_noise_m=0.05, seed=k)
                     for k in range(3)]  # fmt: skip
    flight = fly(rescue, imperfections, release_delays=delays)
    flown = replay(rescue, flight, fuse=True)

    imposed = flown.leave - flown.leave.min()
    assert imposed == pytest.approx(delays, abs=SYNC_S)

    rebuilt = rebuild(rescue, flown)
    assert rebuilt.converged.all(), f"{(~rebuilt.converged).sum()} samples did not converge"
    safe, report = judge(rescue, flown, rebuilt.q)
    assert bool(safe.all()) == (offset <= tolerance), (
        f"offset {offset} s, tolerance {tolerance:.3f} s: {report}"
    )
