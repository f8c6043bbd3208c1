"""A vehicle's clock as the ground reckons it from stamped messages, and its frame (analytic
cases; the frame by ArduPilot's own distance formula)."""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import pytest

from missions.execution.vehicles import VehicleState
from missions.options import GeodeticOrigin
from tests.missions.helpers import approximate_geodetic, ardupilot_distance_ne

#: a LOCAL_POSITION_NED's fields at rest at the origin
STILL = {"x": 0.0, "y": 0.0, "z": 0.0, "vx": 0.0, "vy": 0.0, "vz": 0.0}


class Link:
    def add_listener(self, kinds, listener) -> None:
        self.listener = listener


def heard(state: VehicleState, kind: str, **fields) -> None:
    state._on(SimpleNamespace(get_type=lambda: kind, **fields))


def test_a_silent_vehicle_is_capped_for_targets_and_carried_on_for_a_release(monkeypatch):
    """Speed-up 5: heard at boot 10 s, then 0.1 s of ground time passes in silence. Its
    clock has run 0.5 s; targets are not aimed past 0.1 s after its last message."""
    ground = [100.0]
    monkeypatch.setattr("missions.execution.vehicles.time.monotonic", lambda: ground[0])
    state = VehicleState(Link(), speedup=5.0, max_extrapolation=0.1)
    heard(state, "SYSTEM_TIME", time_boot_ms=10_000, time_unix_usec=1_000_000_000)
    ground[0] += 0.1
    assert state.boot_time() == pytest.approx(10.1)
    assert state.boot_time(capped=False) == pytest.approx(10.5)
    assert state.common_time(capped=False) == pytest.approx(1000.5)


def test_the_least_delayed_message_sets_the_clock(monkeypatch):
    """Two messages, the second 0.05 s of ground time late: the first says more."""
    ground = [100.0]
    monkeypatch.setattr("missions.execution.vehicles.time.monotonic", lambda: ground[0])
    state = VehicleState(Link(), speedup=5.0, max_extrapolation=10.0)
    heard(state, "LOCAL_POSITION_NED", time_boot_ms=10_000, **STILL)
    ground[0] += 0.15  # 0.75 s of the vehicle's time; its next message stamped 10.5 s
    heard(state, "LOCAL_POSITION_NED", time_boot_ms=10_500, **STILL)
    assert state.boot_time() == pytest.approx(10.75)


def test_a_clock_held_back_is_read_from_what_came_after(monkeypatch):
    """Speed-up 2: heard at boot 10 s; its simulator then ran at x1 for 0.1 s of ground time
    and at x2 again, heard at 10.1 s just after. Carried forward at x2, the first message
    puts it 0.1 s ahead of where it is; forgotten, the second one reads it right."""
    ground = [100.0]
    monkeypatch.setattr("missions.execution.vehicles.time.monotonic", lambda: ground[0])
    state = VehicleState(Link(), speedup=2.0, max_extrapolation=10.0)
    heard(state, "LOCAL_POSITION_NED", time_boot_ms=10_000, **STILL)
    ground[0] += 0.1
    heard(state, "LOCAL_POSITION_NED", time_boot_ms=10_100, **STILL)
    assert state.boot_time() == pytest.approx(10.2)
    state.forget_clock_before(ground[0])
    assert state.boot_time() == pytest.approx(10.1)


def test_the_attitude_error_is_the_tilt_from_what_the_controller_asks_for():
    """Rolled 8 deg right and pitched 1 deg up where its controller asks for 2 and -3:
    sqrt(6^2 + 4^2) deg, whatever the lean both share."""
    state = VehicleState(Link(), speedup=1.0, max_extrapolation=0.1)
    assert state.attitude_error() is None
    heard(state, "ATTITUDE", time_boot_ms=1000, roll=math.radians(8.0), pitch=math.radians(1.0),
          yaw=0.0)  # fmt: skip
    assert state.attitude_error() is None  # nothing asked for yet
    heard(state, "NAV_CONTROLLER_OUTPUT", nav_roll=2.0, nav_pitch=-3.0)
    assert state.attitude_error() == pytest.approx(math.hypot(6.0, 4.0))


@pytest.mark.parametrize(
    ("roll", "pitch", "yaw", "north", "east"),
    [
        (10.0, 0.0, 0.0, 0.0, 1.0),  # facing north, rolled right: east
        (0.0, 10.0, 0.0, -1.0, 0.0),  # facing north, nose up: south
        (10.0, 0.0, 90.0, -1.0, 0.0),  # facing east, rolled right: south
    ],
)
def test_the_lean_accelerates_the_drone_along_its_tilt(roll, pitch, yaw, north, east):
    """A lean of 10 deg with the thrust holding the weight: g tan(10 deg) horizontally,
    towards the side the thrust axis leans to."""
    state = VehicleState(Link(), speedup=1.0, max_extrapolation=0.1)
    assert state.lean_acceleration() is None
    heard(state, "ATTITUDE", time_boot_ms=1000, roll=math.radians(roll),
          pitch=math.radians(pitch), yaw=math.radians(yaw))  # fmt: skip
    expected = 9.80665 * math.tan(math.radians(10.0)) * np.array([north, east, 0.0])
    assert state.lean_acceleration() == pytest.approx(expected, abs=1e-12)


def test_a_target_is_placed_in_the_vehicle_s_own_metres_from_its_ekf_origin():
    """EKF origin about 3 m east and 4 m north of the task's origin, home 0.5 m below it: a
    task point 10 m east, 6 m north and 5 m up is given where ArduPilot's own distance from
    that origin puts the point's latitude and longitude (not the task metres from it, about
    7 and 2, which ArduPilot reads 13 mm short and 2.4 mm long at 47.4 deg), and read back
    as the same point."""
    state = VehicleState(Link(), speedup=1.0, max_extrapolation=0.1)
    origin = GeodeticOrigin()
    lat0, lon0 = (round(float(c) * 1e7) for c in approximate_geodetic([3.0, 4.0, 0.0], origin))
    heard(state, "GPS_GLOBAL_ORIGIN", latitude=lat0, longitude=lon0, altitude=488000)
    assert state.frame(origin, home_up=2.0) is None  # no home yet
    heard(state, "HOME_POSITION", z=0.5)
    frame = state.frame(origin, home_up=2.0)
    assert frame is not None
    point = np.array([10.0, 6.0, 5.0])
    lat, lon = approximate_geodetic(point, origin)
    north, east = ardupilot_distance_ne((lat0 * 1e-7, lon0 * 1e-7), lat, lon)
    local = frame.local_position(point)
    assert local == pytest.approx([north, east, 0.5 - (5.0 - 2.0)], abs=2e-5)
    flat = point[[1, 0]] - [frame.origin_north, frame.origin_east]  # task metres from it
    assert abs(local[0] - flat[0]) > 2e-3 and abs(local[1] - flat[1]) > 1e-2
    assert frame.task_position(local) == pytest.approx(point, abs=1e-9)
