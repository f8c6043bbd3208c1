"""The mock's kinematics without sockets: speed profiles and imperfections."""

from __future__ import annotations

import numpy as np
import pymap3d
import pytest
from hypothesis import given
from hypothesis import strategies as st

from missions.export.items import MavCmd, MavFrame
from missions.mock.config import Dynamics, Imperfections
from missions.mock.kinematic_flight import KinematicFlight
from missions.mock.straight import SpeedProfile
from tests.missions.loopback import HOME

from .test_flight import home_item, item

speeds = st.floats(0.0, 8.0)


@given(
    length=st.floats(0.01, 200.0),
    v_in=speeds,
    cruise=st.floats(0.1, 8.0),
    exit_fraction=st.floats(0.0, 1.0),
    accel=st.floats(0.2, 5.0),
)
def test_speed_profile_is_a_bounded_acceleration_ride_along_the_whole_leg(
    length, v_in, cruise, exit_fraction, accel
):
    profile = SpeedProfile.plan(length, v_in, cruise, cruise * exit_fraction, accel)
    t = np.linspace(0.0, profile.duration, 400)
    distance, speed = np.array([profile.at(x) for x in t]).T
    assert distance[-1] == pytest.approx(length, rel=1e-6, abs=1e-9)
    assert np.all(np.diff(distance) >= -1e-9)  # never backwards
    assert np.all(speed >= -1e-9) and np.all(speed <= max(v_in, cruise) + 1e-9)
    assert np.all(np.abs(np.diff(speed)) <= accel * (t[1] - t[0]) + 1e-9)
    # the speed is the derivative of the distance: the mean speed over each interval gives
    # its distance, up to accel * dt^2 / 4 where the interval holds a corner of the profile
    dt = t[1] - t[0]
    middle = 0.5 * (speed[1:] + speed[:-1])
    assert np.allclose(np.diff(distance), middle * dt, atol=accel * dt**2 / 4 + 1e-9)
    v_exit = cruise * exit_fraction
    if v_in <= cruise and abs(v_exit**2 - v_in**2) < 2 * accel * length:
        assert speed[-1] == pytest.approx(v_exit, abs=1e-6)  # reachable: reached


def fly(imperfections: Imperfections, items, dt=0.01, limit=200.0):
    """(times, positions, speeds, events) of a mission flown by the bare flight model."""
    flight = KinematicFlight(HOME, Dynamics(), imperfections, epoch_utc=0.0)
    flight.start(items, 1, HOME.alt_m)
    rows, events, now = [], [], 0.0
    while not flight.finished and now < limit:
        now += dt
        events += [(now, e.kind, e.seq) for e in flight.step(now, dt)]
        rows.append((now, *flight.position, float(np.linalg.norm(flight.velocity))))
    data = np.array(rows)
    return data[:, 0], data[:, 1:4], data[:, 4], events


SQUARE = (
    home_item(),
    item(1, MavCmd.NAV_TAKEOFF, z=10.0),
    item(2, MavCmd.NAV_WAYPOINT, en=(0.0, 20.0), z=10.0),
    item(3, MavCmd.NAV_WAYPOINT, en=(20.0, 20.0), z=10.0),
)


def reached_at(events, seq):
    return next(t for t, kind, s in events if kind == "reached" and s == seq)


def test_full_slowdown_stops_at_every_waypoint():
    t, _, speed, events = fly(Imperfections(waypoint_slowdown=1.0), SQUARE)
    k = int(np.searchsorted(t, reached_at(events, 2)))
    assert speed[k - 1] < 0.1  # nearly stopped just before the corner
    # two separate 20 m legs at 5 m/s, 2.5 m/s^2: 2 s up (5 m), 10 m at 5 m/s, 2 s down
    assert reached_at(events, 3) - reached_at(events, 1) == pytest.approx(2 * 6.0, abs=0.02)
    t, _, speed, events = fly(Imperfections(), SQUARE)
    k = int(np.searchsorted(t, reached_at(events, 2)))
    assert speed[k - 1] == pytest.approx(5.0)  # through the corner at full speed
    # one ramp up, 40 - 10 m at 5 m/s, one ramp down: 2 + 6 + 2 s
    assert reached_at(events, 3) - reached_at(events, 1) == pytest.approx(10.0, abs=0.02)


def test_speed_scale_and_start_delay():
    _, _, speed, _ = fly(Imperfections(speed_scale=0.5), SQUARE)
    assert speed.max() == pytest.approx(2.5)  # half the default 5 m/s (and climb 2.5 x 0.5)
    _, _, _, events = fly(Imperfections(start_delay_s=1.5), SQUARE)
    _, _, _, on_time = fly(Imperfections(), SQUARE)
    assert reached_at(events, 1) - reached_at(on_time, 1) == pytest.approx(1.5, abs=0.011)


def test_position_noise_has_the_configured_spread():
    flight = KinematicFlight(
        HOME, Dynamics(), Imperfections(position_noise_m=0.5, seed=4), epoch_utc=0.0
    )
    samples = np.array(
        [
            pymap3d.geodetic2enu(
                *flight.reported_geodetic(), HOME.lat_deg, HOME.lon_deg, HOME.alt_m
            )
            for _ in range(4000)
        ]
    )
    standing = np.array([0.0, 0.0, Dynamics().rest_height_m])  # on the ground at the origin
    assert samples.std(axis=0) == pytest.approx([0.5, 0.5, 0.5], rel=0.06)
    assert np.abs(samples.mean(axis=0) - standing).max() < 0.05
    assert np.array_equal(flight.position, standing)  # the state itself is not noisy


def test_delay_and_land():
    items = (
        home_item(),
        item(1, MavCmd.NAV_TAKEOFF, z=2.0),
        item(2, MavCmd.NAV_DELAY, frame=MavFrame.MISSION, p1=3.0, p2=-1, p3=-1, p4=-1),
        item(3, MavCmd.NAV_LAND),
    )
    _, p, _, events = fly(Imperfections(), items)
    assert reached_at(events, 2) - reached_at(events, 1) == pytest.approx(3.0, abs=0.011)
    # down to where it stands on the ground, 1.9 m at 0.5 m/s with 2.5 m/s^2 ramps: 0.2 s,
    # 1.8 m cruise, 0.2 s = 4.0 s
    rest = Dynamics().rest_height_m
    assert rest == 0.1
    assert reached_at(events, 3) - reached_at(events, 2) == pytest.approx(4.0, abs=0.011)
    assert p[-1, 2] == pytest.approx(rest)


def test_loiter_unlimited_holds_and_never_completes():
    items = (
        home_item(),
        item(1, MavCmd.NAV_TAKEOFF, z=3.0),
        item(2, MavCmd.NAV_LOITER_UNLIM, en=(5.0, 0.0), z=3.0),
        item(3, MavCmd.NAV_LAND),
    )
    t, p, speed, events = fly(Imperfections(), items, limit=60.0)
    assert t[-1] >= 60.0  # still flying when the test stops it
    assert [(kind, seq) for _, kind, seq in events] == [
        ("current", 1),
        ("reached", 1),
        ("current", 2),
    ]
    assert p[-1] == pytest.approx([5.0, 0.0, 3.0], abs=0.01)  # 1e-7 degree steps
    assert speed[-1] == 0.0


def test_ground_speeds_below_the_minimum_are_ignored_but_not_vertical_ones():
    """ArduCopter's AC_WPNav::set_speed_NE ignores ground speeds below WPNAV_WP_SPEED_MIN
    (20 cm/s up to 4.5); climb and descent speeds have no such floor."""

    def legs(ground: float, climb: float):
        return (
            home_item(),
            item(1, MavCmd.NAV_TAKEOFF, z=2.0),
            item(2, MavCmd.DO_CHANGE_SPEED, frame=MavFrame.MISSION, p1=1, p2=ground, p3=-1),
            item(3, MavCmd.NAV_WAYPOINT, en=(0.0, 2.0), z=2.0, p1=1.0),  # level, then stop
            item(4, MavCmd.DO_CHANGE_SPEED, frame=MavFrame.MISSION, p1=2, p2=climb, p3=-1),
            item(5, MavCmd.NAV_WAYPOINT, en=(0.0, 2.0), z=3.0),  # straight up
        )

    _, _, _, events = fly(Imperfections(), legs(ground=0.15, climb=0.1))
    level = reached_at(events, 3) - reached_at(events, 1)
    # 0.15 m/s ignored: 2 m at the default 5 m/s with 2.5 m/s^2 ramps (1.79 s, no cruise),
    # then the 1 s hold
    assert level == pytest.approx(2 * np.sqrt(2.0 / 2.5) + 1.0, abs=0.02)
    # the 0.1 m/s climb is obeyed: 1 m in 10 s plus 0.04 s of ramps
    assert reached_at(events, 5) - reached_at(events, 3) == pytest.approx(10.04, abs=0.02)
    _, _, _, events = fly(Imperfections(), legs(ground=0.25, climb=0.1))
    # 0.25 m/s obeyed: 0.1 s ramps, 1.975 m at 0.25 m/s, the hold
    assert reached_at(events, 3) - reached_at(events, 1) == pytest.approx(9.1, abs=0.02)


def test_altitudes_are_flown_in_the_centimetres_ardupilot_keeps():
    """AP_Mission stores z * 100.0f truncated to an integer of centimetres."""
    items = (home_item(), item(1, MavCmd.NAV_TAKEOFF, z=2.026),
             item(2, MavCmd.NAV_WAYPOINT, en=(0.0, 1.0), z=1.999))  # fmt: skip
    _, p, _, _ = fly(Imperfections(), items)
    # the top of the takeoff, sampled within 0.13 mm of it (2.5 m/s^2 for 0.01 s from rest)
    assert p[:, 2].max() == pytest.approx(2.02, abs=5e-4)
    assert p[-1, 2] == pytest.approx(1.99, abs=1e-6)  # ENU "up" bends 0.1 um over 1 m
