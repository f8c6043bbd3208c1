"""Kinematic flights in simulated time, checked against hand-computed kinematics."""

from __future__ import annotations

import datetime as dt
import itertools
import math
import time

import numpy as np
import pymap3d
import pytest

from missions.export.items import DroneMission, MavCmd, MavFrame, MissionItem
from missions.mavlink.commands import request_position_stream, send_command
from missions.mavlink.errors import CommandRejectedError
from missions.mavlink.fleet import Fleet
from missions.mavlink.messages import mission_set_current
from missions.mavlink.policy import RetryPolicy
from missions.mavlink.transfer import download_mission
from missions.mavlink.transport import VehicleLink
from missions.mock.autopilot import MockConfig
from missions.mock.config import Imperfections
from missions.mock.kinematic_flight import seconds_until_utc
from missions.mock.sim_clock import SimClock
from tests.missions.loopback import HOME

REL = MavFrame.GLOBAL_RELATIVE_ALT_INT
ACCEL = 2.5  # the mock's default max_accel_mps2 (ArduCopter WPNAV_ACCEL)
CLIMB = 2.5  # default climb speed (WPNAV_SPEED_UP)
SPEEDUP = 20.0


def lat_lon_e7(east: float, north: float) -> tuple[int, int]:
    lat, lon, _ = pymap3d.enu2geodetic(east, north, 0.0, HOME.lat_deg, HOME.lon_deg, HOME.alt_m)
    return round(lat * 1e7), round(lon * 1e7)


def item(seq, command, *, frame=REL, p1=0.0, p2=0.0, p3=0.0, p4=0.0, en=None, z=0.0):
    x, y = lat_lon_e7(*en) if en is not None else (0, 0)
    return MissionItem(
        seq, frame, command, param1=p1, param2=p2, param3=p3, param4=p4, x=x, y=y, z=z
    )


def home_item() -> MissionItem:
    return item(0, MavCmd.NAV_WAYPOINT, frame=MavFrame.GLOBAL, z=HOME.alt_m, en=(0.0, 0.0))


def enu_track(samples) -> tuple[np.ndarray, np.ndarray]:
    """Simulated times [s] and ENU positions [m] of GLOBAL_POSITION_INT samples."""
    t = np.array([s.time_boot_ms / 1000.0 for s in samples])
    e, n, _ = pymap3d.geodetic2enu(
        np.array([s.lat_e7 for s in samples]) * 1e-7,
        np.array([s.lon_e7 for s in samples]) * 1e-7,
        HOME.alt_m,
        HOME.lat_deg,
        HOME.lon_deg,
        HOME.alt_m,
    )
    up = np.array([s.relative_alt_mm for s in samples]) / 1000.0
    return t, np.column_stack([e, n, up])


def crossing_time(t, positions, start, end, after=-math.inf) -> float:
    """When the track, after time ``after``, first passes the midpoint of start->end [s],
    by linear interpolation between the two samples around it."""
    direction = (end - start) / np.linalg.norm(end - start)
    along = (positions - start) @ direction
    goal = 0.5 * np.linalg.norm(end - start)
    k = int(np.argmax((along >= goal) & (t > after)))
    assert along[k] >= goal and t[k] > after and along[k - 1] < goal, "never got there"
    return float(t[k - 1] + (goal - along[k - 1]) / (along[k] - along[k - 1]) * (t[k] - t[k - 1]))


def ramp(v_from: float, v_to: float) -> tuple[float, float]:
    """Time [s] and distance [m] to change speed at the acceleration limit."""
    duration = abs(v_to - v_from) / ACCEL
    return duration, 0.5 * (v_from + v_to) * duration


def first_half(length: float, v_in: float, v: float) -> float:
    """Time from a leg's start to its midpoint: ramp to v, then cruise [s]."""
    t_ramp, d_ramp = ramp(v_in, v)
    assert d_ramp < length / 2
    return t_ramp + (length / 2 - d_ramp) / v


def second_half(length: float, v: float, v_out: float) -> float:
    """Time from a leg's midpoint to its end: cruise, then brake to v_out [s]."""
    t_ramp, d_ramp = ramp(v, v_out)
    assert d_ramp < length / 2
    return (length / 2 - d_ramp) / v + t_ramp


def wait_for(predicate, timeout: float) -> None:
    deadline = time.monotonic() + timeout
    while not predicate():
        assert time.monotonic() < deadline, "timed out"
        time.sleep(0.02)


def test_flown_legs_follow_the_commanded_speeds(spawn_mock, fast_policy):
    a, b, c = np.array([0.0, 30.0, 5.0]), np.array([20.0, 30.0, 5.0]), np.array([0.0, 0.0, 5.0])
    mission = DroneMission(
        1,
        (
            home_item(),
            item(1, MavCmd.NAV_TAKEOFF, z=5.0),
            item(2, MavCmd.DO_CHANGE_SPEED, frame=MavFrame.MISSION, p1=1, p2=3.0, p3=-1),
            item(3, MavCmd.NAV_WAYPOINT, en=a[:2], z=5.0),
            item(4, MavCmd.DO_CHANGE_SPEED, frame=MavFrame.MISSION, p1=1, p2=1.5, p3=-1),
            item(5, MavCmd.NAV_WAYPOINT, en=b[:2], z=5.0, p1=2.0),  # hold 2 s at B
            item(6, MavCmd.DO_CHANGE_SPEED, frame=MavFrame.MISSION, p1=1, p2=4.0, p3=-1),
            item(7, MavCmd.NAV_WAYPOINT, en=c[:2], z=5.0),
        ),
    )
    mock, address = spawn_mock(MockConfig(home=HOME), SimClock(SPEEDUP))
    heartbeats = []
    with Fleet.connect([address], fast_policy) as fleet, fleet.recorder() as recorder:
        fleet.links[0].add_listener(("HEARTBEAT",), heartbeats.append)
        fleet.upload([mission])
        wait_for(lambda: len(heartbeats) >= 5, 2.0)  # 5 simulated seconds
        assert recorder.snapshot()[address].positions == ()  # no stream requested yet
        assert mock.streaming == frozenset()
        fleet.request_position_streams(rate_hz=20.0)
        assert mock.streaming == {"GLOBAL_POSITION_INT", "MISSION_CURRENT"}
        fleet.arm()
        report = fleet.start()
        wait_for(
            lambda: [e.seq for e in recorder.snapshot()[address].reached][-1:] == [7],
            60.0 / SPEEDUP + 2.0,
        )
    telemetry = recorder.snapshot()[address]
    assert report.resent == () and report.spread_s == 0.0
    assert [e.seq for e in telemetry.reached] == [1, 3, 5, 7]  # every nav item, in order
    assert [e.seq for e in telemetry.current if e.seq][:1] == [1]
    assert {1, 3, 5, 7} <= {e.seq for e in telemetry.current}

    t, p = enu_track(telemetry.positions)
    ground = np.array([0.0, 0.0, 0.0])
    above = np.array([0.0, 0.0, 5.0])
    # midpoint crossings happen at cruise speed, so they time the track to milliseconds
    t_up = crossing_time(t, p, ground, above)
    t_a = crossing_time(t, p, above, a)
    t_b = crossing_time(t, p, a, b, after=t_a)
    t_c = crossing_time(t, p, b, c, after=t_b)
    la, lb, lc = (float(np.linalg.norm(e - s)) for s, e in ((above, a), (a, b), (b, c)))
    expected = [
        second_half(5.0, CLIMB, 0.0) + first_half(la, 0.0, 3.0),  # stop on top, then A at 3
        second_half(la, 3.0, 3.0) + first_half(lb, 3.0, 1.5),  # through A, slow to 1.5
        second_half(lb, 1.5, 0.0) + 2.0 + first_half(lc, 0.0, 4.0),  # stop and hold at B
    ]
    measured = [t_a - t_up, t_b - t_a, t_c - t_b]
    # the mock's motion is exact; positions are rounded to 1e-7 degree (about 1 cm), which
    # is a few milliseconds at these speeds
    assert measured == pytest.approx(expected, abs=0.01)

    # positions on the legs: nothing strays from the polyline ground-above-A-B-C
    corners = [ground, above, a, b, c]

    def off_track(q):
        return min(
            np.linalg.norm(
                q - (s + np.clip((q - s) @ (e - s) / ((e - s) @ (e - s)), 0, 1) * (e - s))
            )
            for s, e in itertools.pairwise(corners)
        )

    assert max(off_track(q) for q in p[p[:, 2] > 0.01]) < 0.03  # 1e-7 deg ~ 1 cm steps

    # reported velocity at each midpoint is the commanded speed
    for t_mid, speed in ((t_a, 3.0), (t_b, 1.5), (t_c, 4.0)):
        k = int(np.argmin(abs(t - t_mid)))
        north, east, _ = telemetry.positions[k].velocity_ned_cms
        assert math.hypot(north, east) / 100 == pytest.approx(speed, abs=0.02)


def test_shared_clock_start_delays_and_clock_offsets(spawn_mock, fast_policy):
    """One MISSION_START, three vehicles with start delays, then a NAV_DELAY barrier at an
    absolute UTC second that each vehicle reads from its own (offset) clock."""
    speedup = 10.0  # the start reaches each mock after a few ms of real time: x10, not x20
    epoch_utc = float(math.floor(time.time()))
    clock = SimClock(speedup=speedup, epoch_utc=epoch_utc)
    delays, offsets = (0.0, 0.3, 0.6), (0.0, 0.4, -0.4)
    addresses = [
        spawn_mock(
            MockConfig(
                system_id=k,
                home=HOME,
                imperfections=Imperfections(start_delay_s=delay, clock_offset_s=offset),
            ),
            clock,
        )[1]
        for k, (delay, offset) in enumerate(zip(delays, offsets, strict=True), start=1)
    ]
    with Fleet.connect(addresses, fast_policy) as fleet, fleet.recorder() as recorder:
        # a whole UTC second (the resolution of NAV_DELAY), 8 simulated seconds ahead: time
        # to upload, arm, start and climb 3 m (2.2 s plus the start delay)
        barrier_s = math.ceil(clock.now() + 8.0)
        barrier = dt.datetime.fromtimestamp(epoch_utc + barrier_s, tz=dt.UTC)
        fleet.upload(
            [
                DroneMission(
                    k,
                    (
                        home_item(),
                        item(1, MavCmd.NAV_TAKEOFF, z=3.0),
                        item(
                            2,
                            MavCmd.NAV_DELAY,
                            frame=MavFrame.MISSION,
                            p1=-1,
                            p2=barrier.hour,
                            p3=barrier.minute,
                            p4=barrier.second,
                        ),
                        item(3, MavCmd.NAV_WAYPOINT, en=(0.0, 12.0), z=3.0),
                    ),
                )
                for k in (1, 2, 3)
            ]
        )
        fleet.request_position_streams(rate_hz=20.0)
        fleet.arm()
        report = fleet.start()
        wait_for(
            lambda: all(v.reached and v.reached[-1].seq == 3 for v in recorder.snapshot().values()),
            20.0 / speedup + 2.0,
        )
    tracks = [enu_track(recorder.snapshot()[a].positions) for a in addresses]
    up, north = np.array([0.0, 0.0, 3.0]), np.array([0.0, 12.0, 3.0])
    lift = [crossing_time(t, p, np.zeros(3), up) for t, p in tracks]
    leave = [crossing_time(t, p, up, north) for t, p in tracks]
    # Real-time jitter is multiplied by the speed-up (x10): bounds allow ~10 ms of it, which
    # a loaded 2-core machine produces (a 5 ms bound failed while a benchmark ran).
    assert report.resent == () and report.spread_s < 0.05  # sent back to back
    assert max(lift) + 1.1 < barrier_s - max(offsets)  # all waited at the barrier
    # time_boot_ms of all three count from the shared epoch, so they compare directly
    assert [x - lift[0] for x in lift] == pytest.approx(delays, abs=0.1)
    # a clock ahead by 0.4 s releases 0.4 s early; the release itself is exact, and the
    # midpoint is crossed 2.2 s later (2 s ramp to 5 m/s, 1 m at 5 m/s)
    assert [x - leave[0] for x in leave] == pytest.approx([-o for o in offsets], abs=0.1)
    assert leave[0] - barrier_s == pytest.approx(2.2, abs=0.1)


def test_mission_start_is_refused_while_disarmed(spawn_mock, fast_policy):
    _, address = spawn_mock()
    with VehicleLink(address, fast_policy, name="v") as link:
        link.wait_heartbeat()
        with pytest.raises(CommandRejectedError) as error:
            send_command(link, int(MavCmd.MISSION_START), (), fast_policy)
    assert (error.value.vehicle, error.value.command) == ("v", 300)
    assert (error.value.result, error.value.result_name) == (2, "MAV_RESULT_DENIED")


@pytest.mark.parametrize(
    ("hms", "expected"),
    [
        ((12, 1, 0), 29.75),
        ((12, 0, 30), 24 * 3600 - 0.25),  # just past: the same time tomorrow
        ((-1, 5, 0), 269.75),  # hour ignored: 12:05:00
        ((-1, -1, 40), 9.75),  # minute ignored too: 12:00:40
        ((-1, -1, 20), 49.75),  # ... already past this minute: 12:01:20
        ((-1, -1, -1), 0.0),
    ],
)
def test_nav_delay_utc_time_of_day(hms, expected):
    now = dt.datetime(2024, 3, 1, 12, 0, 30, 250_000, tzinfo=dt.UTC).timestamp()
    assert seconds_until_utc(now, *hms) == pytest.approx(expected)


def test_arming_makes_the_current_position_the_home(spawn_mock, fast_policy):
    """Fly 10 m north and land there (the mock disarms on touchdown); arming again moves
    home, and seq 0 reads back as the new home: where the vehicle stands, its rest height
    above the ground (SITL, started with --home at 488.0 m, read back a home of 488.06 m,
    its estimate of SIM_STATE's 488.10 m)."""
    mock, address = spawn_mock(MockConfig(home=HOME), SimClock(SPEEDUP))
    mission = DroneMission(
        1,
        (
            home_item(),
            item(1, MavCmd.NAV_TAKEOFF, z=2.0),
            item(2, MavCmd.NAV_WAYPOINT, en=(0.0, 10.0), z=2.0),
            item(3, MavCmd.NAV_LAND),
        ),
    )
    with Fleet.connect([address], fast_policy) as fleet, fleet.recorder() as recorder:
        fleet.upload([mission])
        fleet.arm()
        fleet.start()
        wait_for(
            lambda: [e.seq for e in recorder.snapshot()[address].reached][-1:] == [3],
            20.0 / SPEEDUP + 2.0,
        )
        wait_for(lambda: not mock.armed, 1.0)
        fleet.arm()
        (home,) = download_mission(fleet.links[0], fast_policy)[:1]
    east, north, up = pymap3d.geodetic2enu(
        home.x * 1e-7, home.y * 1e-7, home.z, HOME.lat_deg, HOME.lon_deg, HOME.alt_m
    )
    assert (east, north, up) == pytest.approx((0.0, 10.0, 0.1), abs=0.02)
    assert (home.frame, home.command) == (MavFrame.GLOBAL, MavCmd.NAV_WAYPOINT)
    assert mock.home.lat_deg == pytest.approx(home.x * 1e-7, abs=1e-7)


def test_mission_set_current_chooses_where_mission_start_begins(spawn_mock, fast_policy):
    _, address = spawn_mock()
    mission = DroneMission(
        1,
        (
            home_item(),
            item(1, MavCmd.NAV_TAKEOFF, z=2.0),
            item(2, MavCmd.NAV_WAYPOINT, en=(0.0, 10.0), z=2.0),
        ),
    )
    with Fleet.connect([address], fast_policy) as fleet:
        link = fleet.links[0]
        fleet.upload([mission])
        fleet.arm()
        with link.subscribe(("MISSION_CURRENT",)) as inbox:
            link.send(mission_set_current(2, link.target))
            assert inbox.get(1.0).seq == 2
            link.send(mission_set_current(9, link.target))  # no such item: unchanged
            assert inbox.get(1.0).seq == 2
        # from item 2 on the ground there is no takeoff: ArduCopter refuses (FAILED)
        with pytest.raises(CommandRejectedError) as error:
            send_command(link, int(MavCmd.MISSION_START), (), fast_policy)
        assert error.value.result_name == "MAV_RESULT_FAILED"
        link.send(mission_set_current(1, link.target))
        send_command(link, int(MavCmd.MISSION_START), (), fast_policy)


class IntervalDroppingLink(VehicleLink):
    """A link on which MAV_CMD_SET_MESSAGE_INTERVAL never gets through."""

    def send(self, spec):
        if spec[0] == "COMMAND_LONG" and spec[1]["command"] == 511:
            return
        super().send(spec)


def test_stream_request_falls_back_to_request_data_stream(spawn_mock):
    mock, address = spawn_mock()
    policy = RetryPolicy(
        request_timeout_s=0.2, retries=1, heartbeat_timeout_s=3.0, gcs_heartbeat_interval_s=0.1
    )
    with IntervalDroppingLink(address, policy) as link:
        link.wait_heartbeat()
        assert mock.streaming == frozenset()
        request_position_stream(link, 5.0, policy)
    # REQUEST_DATA_STREAM(POSITION) turned on the position stream only
    assert mock.streaming == {"GLOBAL_POSITION_INT"}


def test_disarm_is_refused_in_the_air_unless_forced(spawn_mock, fast_policy):
    mock, address = spawn_mock(MockConfig(home=HOME), SimClock(SPEEDUP))
    mission = DroneMission(
        1,
        (home_item(), item(1, MavCmd.NAV_TAKEOFF, z=2.0), item(2, MavCmd.NAV_LOITER_UNLIM, z=2.0)),
    )
    with Fleet.connect([address], fast_policy) as fleet, fleet.recorder() as recorder:
        link = fleet.links[0]
        fleet.upload([mission])
        fleet.arm()
        fleet.start()
        wait_for(lambda: [e.seq for e in recorder.snapshot()[address].reached] == [1], 2.0)
        with pytest.raises(CommandRejectedError) as error:
            send_command(link, 400, (0.0,), fast_policy)  # MAV_CMD_COMPONENT_ARM_DISARM
        assert error.value.result_name == "MAV_RESULT_DENIED" and mock.armed
        send_command(link, 400, (0.0, 21196.0), fast_policy)  # forced
        assert not mock.armed
