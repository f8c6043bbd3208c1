"""Following a drone that cannot keep its targets: the others' targets move by its
deviation, velocity and lean (analytic cases), as little as keeps the load safe with room
to spare (the scene's checker and the model's statics), and a weak motor seen in the
telemetry sets it off."""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import pytest

from flycrane.model.direct_kinematics import configuration_from_drone_positions
from flycrane.model.kinematics import drone_positions_from_configuration
from flycrane.model.statics import evaluate_statics
from flycrane.planning.problem import PlanningProblem
from flycrane.world.scene import load_scene
from missions.autopilots.location import VehicleFrame
from missions.execution.anchor import FRACTIONS, LIMIT, ROOM_MARGIN_N, Anchor, FormationRoom
from missions.execution.record import ExecutionRecord
from missions.execution.team import EKF_NEEDED
from missions.execution.vehicles import VehicleState
from missions.trajectory.drone_trajectory import DroneTrajectory
from tests.missions.execution.test_stream import _executor, _Link

#: A frame whose metres are the task's, so that the analytic cases read as they are written.
FRAME = VehicleFrame(
    origin_east=0.0, origin_north=0.0, scale=(1.0, 1.0), home_down=0.0, home_up=0.0
)
STILL = (np.zeros(3), np.zeros(3), np.zeros(3))


def heard(state: VehicleState, kind: str, **fields) -> None:
    state._on(SimpleNamespace(get_type=lambda: kind, **fields))


def _at(
    state: VehicleState, north: float, east: float, up: float, v_north: float, roll: float = 0.0
) -> None:
    """Heard at boot 3 s = common time 103 s, at (north, east, up), moving north, facing
    north and rolled ``roll`` [deg] right."""
    heard(state, "SYSTEM_TIME", time_boot_ms=3000, time_unix_usec=103_000_000)
    heard(state, "LOCAL_POSITION_NED", time_boot_ms=3000, x=north, y=east, z=-up,
          vx=v_north, vy=0.0, vz=0.0)  # fmt: skip
    heard(state, "ATTITUDE", time_boot_ms=3000, roll=math.radians(roll), pitch=0.0, yaw=0.0)


def test_the_shift_is_the_deviation_carried_on_with_its_velocity():
    """Its target still at the origin; the drone 0.3 m north, 0.1 m east and 0.2 m up,
    moving north at 0.5 m/s: 0.1 s after its estimate the others move by (0.1, 0.35, 0.2)
    m (ENU), at 0.5 m/s north."""
    state = VehicleState(_Link(), speedup=1.0, max_extrapolation=0.1)  # type: ignore[arg-type]
    _at(state, north=0.3, east=0.1, up=0.2, v_north=0.5)
    shift, velocity, acceleration = Anchor(
        state, FRAME, np.zeros(3), lambda t: STILL, lambda t: 0.0, 0, None
    ).shift(103.1)
    assert shift == pytest.approx([0.1, 0.35, 0.2])
    assert velocity == pytest.approx([0.0, 0.5, 0.0])
    assert acceleration == pytest.approx(np.zeros(3))


def test_the_others_are_pushed_as_the_faulty_drone_leans():
    """Facing north and rolled 6 deg right where its target accelerates 0.2 m/s^2 east
    and 0.1 m/s^2 up: the others get the lean's g tan(6 deg) east beyond the target's,
    nothing vertically."""
    state = VehicleState(_Link(), speedup=1.0, max_extrapolation=0.1)  # type: ignore[arg-type]
    _at(state, north=0.0, east=0.0, up=0.0, v_north=0.0, roll=6.0)
    target = (np.zeros(3), np.zeros(3), np.array([0.2, 0.0, 0.1]))
    acceleration = Anchor(
        state, FRAME, np.zeros(3), lambda t: target, lambda t: 0.0, 0, None
    ).shift(103.0)[2]
    lean = 9.80665 * math.tan(math.radians(6.0))
    assert acceleration == pytest.approx([lean - 0.2, 0.0, 0.0])


def test_a_drone_leaving_beyond_the_limit_is_followed_no_farther():
    state = VehicleState(_Link(), speedup=1.0, max_extrapolation=0.1)  # type: ignore[arg-type]
    _at(state, north=0.0, east=3.0, up=-4.0, v_north=0.0)
    shift, velocity, acceleration = Anchor(
        state, FRAME, np.zeros(3), lambda t: STILL, lambda t: 0.0, 0, None
    ).shift(103.0)
    assert np.linalg.norm(shift) == pytest.approx(LIMIT)
    assert shift == pytest.approx(np.array([3.0, 0.0, -4.0]) * LIMIT / 5.0)
    assert velocity == pytest.approx(np.zeros(3))
    assert acceleration == pytest.approx(np.zeros(3))


def _stream(
    executor, deviation: np.ndarray, drift: np.ndarray, roll: float, fix_type: int = 6
) -> None:
    """Every drone heard at common time 103 s on its target, in GUIDED with a usable
    estimate, except drone 2: ``deviation`` and ``drift`` off it and rolled ``roll`` [deg]
    right where its controller asks for none; drone 3's GNSS fix ``fix_type``."""
    for k, vehicle in enumerate(executor.vehicles):
        p, v, _ = executor.target(k, 103.0)
        if k == 1:
            p, v = p + deviation, v + drift
        east, north, up = p
        _at(vehicle, north=north, east=east, up=up, v_north=v[1])
        vehicle.velocity = np.array([v[1], v[0], -v[2]])  # NED
        heard(vehicle, "HEARTBEAT", custom_mode=executor.expected_mode, system_status=4)
        heard(vehicle, "EKF_STATUS_REPORT", flags=EKF_NEEDED)
        heard(vehicle, "GPS_RAW_INT", fix_type=fix_type if k == 2 else 6)
        heard(vehicle, "ATTITUDE", time_boot_ms=3000, roll=math.radians(roll if k == 1 else 1.0),
              pitch=0.0, yaw=0.0)  # fmt: skip
        heard(vehicle, "NAV_CONTROLLER_OUTPUT", nav_roll=0.0, nav_pitch=0.0)


def _stopped_executor():
    executor = _executor(None)
    executor.frames = [FRAME] * 3
    executor.record = ExecutionRecord(mode="stream", start=100.0, duration=10.0, offsets=[0.0] * 3,
                                      frames=[])  # fmt: skip
    return executor


def _assert_the_others_follow_drone_2(executor, deviation: np.ndarray, drift: np.ndarray) -> None:
    """0.1 s after its estimate drones 1 and 3 are sent their targets moved by drone 2's
    deviation and drift and pushed by its 7 deg lean; drone 2 its own."""
    t = 103.1
    # rolled 7 deg right facing north: pushed east beyond its target's acceleration
    push = np.array([9.80665 * math.tan(math.radians(7.0)), 0.0, 0.0])
    push[:2] -= executor.target(1, 103.0)[2][:2]
    for k in (0, 2):
        p, v, a = executor.target(k, t)
        moved = executor.commanded(k, t)
        assert moved[0] == pytest.approx(p + deviation + drift * 0.1)
        assert moved[1] == pytest.approx(v + drift)
        assert moved[2] == pytest.approx(a + push)
    own = executor.commanded(1, t)
    assert own[0] == pytest.approx(executor.target(1, t)[0])


def test_a_weak_motor_stops_the_team_and_the_others_keep_the_formation_on_it():
    """Drone 2 tilted 7 deg from what its controller asks for, 0.3 m east and 0.1 m below
    its target and drifting east at 0.4 m/s faster than it: the team stops, drones 1 and
    3 are sent their targets moved by that and pushed by its lean, drone 2 its own."""
    executor = _stopped_executor()
    deviation, drift = np.array([0.3, 0.0, -0.1]), np.array([0.4, 0.0, 0.0])
    _stream(executor, deviation, drift, roll=7.0)
    faults = executor._judge(103.0)
    assert {(f.drone, str(f.kind)) for f in faults} == {(2, "attitude"), (2, "stray")}
    assert executor.stopped
    _assert_the_others_follow_drone_2(executor, deviation, drift)


def test_a_weak_motor_during_the_hold_after_another_fault_is_followed_too():
    """Drone 3's GNSS fix lost stops the team, and the others hold at their targets; then
    drone 2 weakens during the hold (tilted and off its target as above): drones 1 and 3
    follow it as they would had it stopped the team."""
    executor = _stopped_executor()
    still = np.zeros(3)
    _stream(executor, still, still, roll=1.0, fix_type=1)
    faults = executor._judge(103.0)
    assert [(f.drone, str(f.kind)) for f in faults] == [(3, "gps")]
    assert executor.stopped
    for k in (0, 2):
        assert executor.commanded(k, 103.1)[0] == pytest.approx(executor.target(k, 103.1)[0])
    deviation, drift = np.array([0.3, 0.0, -0.1]), np.array([0.4, 0.0, 0.0])
    _stream(executor, deviation, drift, roll=7.0, fix_type=1)
    faults = executor._judge(103.0)
    assert {(f.drone, str(f.kind)) for f in faults} == {(2, "attitude"), (2, "stray")}
    _assert_the_others_follow_drone_2(executor, deviation, drift)


def test_the_others_follow_as_little_as_keeps_the_load_safe_with_room_to_spare():
    """The Puzzle's start formation, standing still, drone 1 off by a shift: nothing to
    follow where it is not off; 0.6 m north (the load safe with the others at their
    stops, but a margin below ROOM_MARGIN_N, as the model's statics find) and 0.8 m north
    (cable 1 slack there, as the checker finds) the least fraction at which the load with
    the others moved by it is safe and keeps the margin, no smaller one; 40 m down nothing
    safe and nothing clear: the others stay."""
    problem = PlanningProblem.from_scene(load_scene("puzzle")[0])
    drones = drone_positions_from_configuration(problem.system, problem.start)[0]
    homes = drones - [0.0, 0.0, 0.1]
    positions = np.repeat((drones - homes)[None], 2, axis=0)
    trajectory = DroneTrajectory(time=np.array([0.0, 1.0]), position=positions,
                                 velocity=np.zeros_like(positions),
                                 acceleration=np.zeros_like(positions), homes=homes)  # fmt: skip
    checker = problem.validity.with_clearance(0.07)
    room = FormationRoom(problem.system, trajectory, checker)

    def outcome(shift: np.ndarray, fraction: float) -> tuple[bool, float]:
        """Safe, and the least statics margin [N], with the others moved by ``fraction``."""
        moved = drones + fraction * shift
        moved[0] = drones[0] + shift
        solved = configuration_from_drone_positions(problem.system, moved[None])
        report = evaluate_statics(problem.system, solved.q)
        least = min(report.slack_margin.min(), report.overload_margin.min(),
                    report.thrust_margin.min())  # fmt: skip
        return bool(solved.converged[0] and checker.is_safe(solved.q)[0]), float(least)

    assert room(0.5, np.zeros(3), 0) == 0.0
    needed = min(ROOM_MARGIN_N, outcome(np.zeros(3), 0.0)[1])
    assert outcome(np.array([0.0, 0.6, 0.0]), 0.0)[0]
    assert not outcome(np.array([0.0, 0.8, 0.0]), 0.0)[0]
    for north in (0.6, 0.8):
        shift = np.array([0.0, north, 0.0])
        fraction = room(0.5, shift, 0)
        safe, margin = outcome(shift, fraction)
        assert fraction > 0.0 and safe and margin >= needed
        for smaller in (f for f in (0.0, *FRACTIONS) if f < fraction):
            safe, margin = outcome(shift, smaller)
            assert not safe or margin < needed
    assert room(0.5, np.array([0.0, 0.0, -40.0]), 0) == 0.0
