"""Spline waypoint legs in the mock: the path, the speed limits, and the timing of the model
of :mod:`missions.autopilots` (which ``test_mock_vs_sitl`` holds against SITL)."""

from __future__ import annotations

import time

import numpy as np
import pytest

from missions.autopilots.chain import fly_chain
from missions.autopilots.spline import SpeedLimits
from missions.export.items import DroneMission, MavCmd, MavFrame
from missions.mavlink.commands import request_position_stream
from missions.mavlink.fleet import Fleet
from missions.mavlink.messages import mission_set_current
from missions.mock.autopilot import MockConfig
from missions.mock.config import Dynamics, Imperfections
from missions.mock.kinematic_flight import KinematicFlight, default_settings
from missions.mock.sim_clock import SimClock
from tests.missions.loopback import HOME

from .test_flight import enu_track, home_item, item, wait_for

DT = 0.0025  # ArduCopter's loop: the bare flights below step at it
SPLINE, HOLD, SPEED = MavCmd.NAV_SPLINE_WAYPOINT, MavCmd.NAV_LOITER_UNLIM, MavCmd.DO_CHANGE_SPEED
GROUND, CLIMB, DESCENT = 1, 2, 3


def speed(seq: int, kind: int, value: float):
    return item(seq, SPEED, frame=MavFrame.MISSION, p1=kind, p2=value, p3=-1)


def enu(east: float, north: float, up: float) -> np.ndarray:
    """Where the mock flies an item placed at (east, north, up): its latitude and longitude
    are whole 1e-7 degrees (about 1 cm), its altitude whole centimetres."""
    return KinematicFlight(HOME, Dynamics(), Imperfections(), 0.0).enu_from_item(
        item(1, SPLINE, en=(east, north), z=up), HOME.alt_m
    )


def released(items, release_seq: int, limit_s: float = 120.0):
    """Fly ``items`` on a bare mock: take off, hold, then jump to ``release_seq`` (the
    release); the times [s from the release], positions and events after it."""
    flight = KinematicFlight(HOME, Dynamics(), Imperfections(), epoch_utc=0.0)
    flight.start(items, 1, HOME.alt_m)
    now = 0.0
    while not any(e.kind == "current" and e.seq == release_seq - 1 for e in flight.step(now, DT)):
        now += DT
    flight.jump(items, release_seq, HOME.alt_m)
    rows, events, t = [], [], 0.0
    while not flight.finished and t < limit_s:
        t += DT
        # an item started within a step is reported at its end: time it by the step's start
        events += [(t - DT, e.kind, e.seq) for e in flight.step(now + t, DT)]
        rows.append((t, *flight.position, float(np.linalg.norm(flight.velocity))))
        if events and events[-1][1:] == ("current", len(items) - 1):
            break
    data = np.array(rows)
    return data[:, 0], data[:, 1:4], data[:, 4], events


def starts(events, kind="current"):
    return {seq: t for t, k, seq in events if k == kind}


def chain_mission(points, speed_items):
    """Takeoff to the first point, hold there, then per leg its DO items and a spline
    waypoint, and a hold at the last point."""
    items = [home_item(), item(1, MavCmd.NAV_TAKEOFF, z=points[0][2]),
             item(2, HOLD, en=points[0][:2], z=points[0][2])]  # fmt: skip
    for point, dos in zip(points[1:], speed_items, strict=True):
        items += [speed(len(items) + i, kind, value) for i, (kind, value) in enumerate(dos)]
        items.append(item(len(items), SPLINE, en=point[:2], z=point[2]))
    items.append(item(len(items), HOLD, en=points[-1][:2], z=points[-1][2]))
    return tuple(items)


def test_collinear_spline_waypoints_are_flown_on_their_line_and_stop_at_the_end():
    """Collinear waypoints make every spline term parallel to the line (AC_WPNav's tangents
    are along it), and the hold at the last one makes it a stop."""
    points = [(0.0, 0.0, 5.0), (0.0, 4.0, 5.0), (0.0, 8.0, 5.0), (0.0, 12.0, 5.0)]
    items = chain_mission(points, [[(GROUND, 1.0)], [], []])
    _, p, v, events = released(items, 3)
    # on the line, but for the Earth's curvature: ENU "up" falls by d^2 / 2R, 11 um at 12 m
    start, end = enu(*points[0]), enu(*points[-1])
    axis = (end - start) / np.linalg.norm(end - start)
    off = (p - start) - np.outer((p - start) @ axis, axis)
    assert np.linalg.norm(off, axis=1).max() < 2e-5
    assert np.all(np.diff(p[:, 1]) >= -1e-12)  # never backwards
    assert v.max() == pytest.approx(1.0, abs=1e-9)  # the ground speed it was given
    assert p[-1] == pytest.approx(enu(*points[-1]), abs=1e-12) and v[-1] == 0.0
    assert [(k, s) for _, k, s in events] == [("current", 4), ("reached", 4), ("current", 5),
        ("reached", 5), ("current", 6), ("reached", 6), ("current", 7)]  # fmt: skip


def test_legs_take_the_times_the_autopilot_model_gives_them():
    """A curved 3-D chain whose speed changes every leg, with two DO items before a leg
    (only the first acts before the leg is set up), flown by the mock as by the model."""
    points = [(0.0, 0.0, 4.0), (1.5, 2.0, 4.5), (3.5, 2.5, 4.3), (4.0, 4.0, 3.6), (2.0, 5.0, 3.6)]
    dos = [[(GROUND, 0.6)], [(CLIMB, 0.3), (DESCENT, 0.25)], [(GROUND, 0.4), (DESCENT, 0.2)],
           [(GROUND, 0.7)]]  # fmt: skip
    items = chain_mission(points, dos)
    _, _, _, events = released(items, 3)
    spline_seqs = [i.seq for i in items if i.command == SPLINE]
    reached = starts(events, "reached")
    flown = np.array([reached[s] for s in spline_seqs])

    settings = default_settings()  # the mock's parameters are ArduCopter's defaults
    limits, current = [], settings.initial_speeds
    for leg in dos:
        for kind, value in leg:
            current = SpeedLimits(**{**current.__dict__, {1: "horizontal", 2: "up", 3: "down"}[
                kind]: value})  # fmt: skip
        limits.append(current)
    model = fly_chain(np.array([enu(*p) for p in points]), limits, settings.accel_limits,
                      settings.initial_speeds, settings.tracking, dt=DT)  # fmt: skip
    # within the step the mock reports a leg's end in, whichever side of it float sums land
    assert flown == pytest.approx(model.arrival[1:], abs=2 * DT)


def test_ground_speeds_below_the_floor_are_ignored_but_not_vertical_ones():
    level = [(0.0, 0.0, 2.0), (0.0, 3.0, 2.0)]
    for ground, slowest in ((0.15, False), (0.25, True)):
        _, _, v, events = released(chain_mission(level, [[(GROUND, ground)]]), 3)
        duration = starts(events, "reached")[4]
        # ignored: the default 10 m/s (ArduCopter's WPNAV_SPEED), accel-limited; obeyed:
        # 3 m at 0.25 m/s
        assert (duration >= 3.0 / 0.25) is slowest
        assert v.max() <= (0.25 if slowest else 10.0) + 1e-9
    up = [(0.0, 0.0, 2.0), (0.0, 0.0, 3.0)]
    _, _, v, events = released(chain_mission(up, [[(CLIMB, 0.1)]]), 3)
    assert 10.0 <= starts(events, "reached")[4] < 11.0 and v.max() == pytest.approx(0.1)


def test_the_release_from_the_hold_runs_the_do_items_then_the_spline_leg(spawn_mock, fast_policy):
    """MISSION_SET_CURRENT to the DO item after the hold, as the ground station releases the
    drones."""
    mock, address = spawn_mock(MockConfig(home=HOME), SimClock(20.0))
    north = (0.0, 4.0, 3.0)
    mission = DroneMission(1, chain_mission([(0.0, 0.0, 3.0), north], [[(GROUND, 0.5)]]))
    with Fleet.connect([address], fast_policy) as fleet, fleet.recorder() as recorder:
        link = fleet.links[0]
        fleet.upload([mission])
        request_position_stream(link, 50.0, fast_policy)
        fleet.arm()
        fleet.start()
        wait_for(lambda: [e.seq for e in recorder.snapshot()[address].current][-1:] == [2], 2.0)
        with link.subscribe(("MISSION_CURRENT",)) as inbox:
            link.send(mission_set_current(3, link.target))
            # periodic reports of the hold (20 a second at this speed-up) may come first,
            # as many as the machine's load delays the mock: skip them, the next is the answer
            until = time.monotonic() + 10.0
            answer = inbox.get(5.0)
            while answer is not None and answer.seq == 2 and time.monotonic() < until:
                answer = inbox.get(5.0)
        assert answer is not None and answer.seq == 3  # item 3 confirmed, not skipped past
        wait_for(lambda: 4 in [e.seq for e in recorder.snapshot()[address].reached], 3.0)
    telemetry = recorder.snapshot()[address]
    seqs = [e.seq for e in telemetry.current]  # periodic as well as on every change
    changes = [s for previous, s in zip([None, *seqs], seqs, strict=False) if s != previous]
    assert changes[-4:] == [2, 3, 4, 5]
    t, p = enu_track(telemetry.positions)
    speeds = [np.hypot(*s.velocity_ned_cms[:2]) / 100 for s in telemetry.positions]
    # the DO item's ground speed, from the start: the vehicle (reported) overshoots its
    # target's 0.5 m/s by a few percent while it catches up, having no feed-forward
    assert 0.45 <= max(speeds) <= 0.5 * 1.15
    left, arrived = t[p[:, 1] > 0.01][0], t[p[:, 1] > 3.9][0]
    assert arrived - left >= 3.9 / 0.5
    # the target, above the home arming set where the mock stood, its rest height up
    standing = np.array([0.0, 0.0, Dynamics().rest_height_m])
    assert mock.flight.position == pytest.approx(enu(*north) + standing, abs=1e-6)
