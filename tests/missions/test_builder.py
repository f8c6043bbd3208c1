"""Per-drone MAVLink missions: structure, home, positions, altitudes, speeds, start barrier.

Leg durations are recomputed here from the item list with ArduCopter's track-speed rule
(AC_WPNav / SCurve ``kinematic_limit``: the speed along a leg is
``min(ground_speed / horizontal_fraction, climb_or_descent_speed / vertical_fraction)``),
walking the DO_CHANGE_SPEED items the way the autopilot keeps its limits. Positions are
checked against a first-order conversion through the WGS84 radii of curvature. Both are in
``tests/missions/helpers.py``, written without the modules under test.
"""

from __future__ import annotations

import time
from datetime import UTC, datetime, timedelta, timezone

import numpy as np
import pytest

from missions.builder import LegSpeeds, build_missions
from missions.items import MavCmd, MavFrame
from missions.options import MissionOptions
from tests.missions.helpers import (
    approximate_geodetic,
    encoded_leg_vectors,
    flown_leg_durations,
    hand_made_plan,
    nav_waypoints,
)

# 1 m legs of 10 s with slow, slightly different vertical components: 1.5 then 2.4 mm/s of
# climb, then 2.0 then 2.8 mm/s of descent (a near-level carry, as when a load is levelled).
NEAR_LEVEL = hand_made_plan(
    [[1.0, 0.0, 0.015], [1.0, 0.0, 0.024], [1.0, 0.0, -0.020], [0.0, 1.0, -0.028]],
    [10.0, 10.0, 10.0, 10.0],
)


@pytest.fixture(scope="module")
def missions(curved_plan):
    return build_missions(curved_plan, MissionOptions())


def test_every_drone_has_the_same_structure_and_one_nav_waypoint_per_leg(curved_plan, missions):
    assert [m.drone for m in missions] == [1, 2, 3]
    for mission in missions:
        items = mission.items
        assert [it.seq for it in items] == list(range(len(items)))
        assert items[0].command == MavCmd.NAV_WAYPOINT
        assert items[1].command == MavCmd.NAV_TAKEOFF
        assert items[2].command == MavCmd.NAV_WAYPOINT and items[2].param1 == 5.0
        assert items[-1].command == MavCmd.NAV_LOITER_UNLIM
        assert len(nav_waypoints(mission)) == len(curved_plan.time) - 1
        middle = {it.command for it in items[3:-1]}
        assert middle <= {MavCmd.NAV_WAYPOINT, MavCmd.DO_CHANGE_SPEED}


def test_home_is_on_the_ground_below_each_drone_start(curved_plan, missions):
    origin = MissionOptions().origin
    for j, mission in enumerate(missions):
        home, takeoff, start = mission.items[:3]
        assert home.frame == MavFrame.GLOBAL_INT  # AMSL
        assert home.z == pytest.approx(origin.altitude, abs=1e-4)
        assert (home.x, home.y) == (takeoff.x, takeoff.y) == (start.x, start.y)
        lat, lon = approximate_geodetic(curved_plan.drones[0, j], origin)
        assert abs(home.x - lat * 1e7) <= 0.5 + 0.01
        assert abs(home.y - lon * 1e7) <= 0.5 + 0.01
        assert takeoff.z == start.z == pytest.approx(curved_plan.drones[0, j, 2])


def test_positions_are_the_planned_drone_positions_rounded_to_the_nearest_unit(
    curved_plan, missions
):
    origin = MissionOptions().origin
    errors = []
    for j, mission in enumerate(missions):
        items = [mission.items[2], *nav_waypoints(mission)]
        lat, lon = approximate_geodetic(curved_plan.drones[:, j], origin)
        errors += [it.x - la * 1e7 for it, la in zip(items, lat, strict=True)]
        errors += [it.y - lo * 1e7 for it, lo in zip(items, lon, strict=True)]
        for item, z in zip(items, curved_plan.drones[:, j, 2], strict=True):
            assert item.frame == MavFrame.GLOBAL_RELATIVE_ALT_INT
            assert item.z == pytest.approx(z, abs=1e-9)
            assert item.param2 == 0.2  # acceptance radius
    # Nearest 1e-7 degree: never more than half a unit off (truncation would reach 1).
    assert np.abs(errors).max() <= 0.5 + 0.01


def test_amsl_altitudes_add_the_origin_altitude(curved_plan):
    options = MissionOptions(altitude_frame="amsl")
    for j, mission in enumerate(build_missions(curved_plan, options)):
        items = [mission.items[1], mission.items[2], *nav_waypoints(mission)]
        heights = curved_plan.drones[[0, *range(len(curved_plan.time))], j, 2]
        for item, z in zip(items, heights, strict=True):
            assert item.frame == MavFrame.GLOBAL_INT
            assert item.z == pytest.approx(options.origin.altitude + z, abs=1e-5)


@pytest.mark.parametrize("which", ["curved", "near level"])
def test_speed_changes_make_every_leg_last_its_planned_duration(curved_plan, which):
    plan = curved_plan if which == "curved" else NEAR_LEVEL
    planned = np.diff(plan.time)
    options = MissionOptions()
    for j, mission in enumerate(build_missions(plan, options)):
        # The autopilot flies between the waypoints as encoded (rounded coordinates,
        # centimetre altitudes), so the legs are measured there.
        flown = flown_leg_durations(mission, encoded_leg_vectors(mission, options.origin))
        # Within 0.1 %: a 10 s leg 10 ms early or late (speed items are not repeated for
        # smaller changes).
        np.testing.assert_allclose(flown, planned, rtol=1e-3, err_msg=f"drone {j + 1}")


def test_a_change_of_direction_alone_does_not_repeat_speed_items():
    # Same speeds on both legs, east then north: ground speed items only, and a second one
    # only where rounding to 1e-7 degree makes the encoded legs differ by more than 0.1 %.
    plan = hand_made_plan([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0]], [4.0, 4.0])
    options = MissionOptions()
    for mission in build_missions(plan, options):
        speeds = [it for it in mission.items if it.command == MavCmd.DO_CHANGE_SPEED]
        lengths = np.linalg.norm(encoded_leg_vectors(mission, options.origin), axis=1)
        differ = abs(lengths[1] - lengths[0]) > 1e-3 * lengths[1]
        assert [it.param1 for it in speeds] == [1.0] * (1 + differ)
        assert speeds[0].param2 == pytest.approx(lengths[0] / 4.0, rel=1e-5)


@pytest.mark.parametrize(
    ("given", "hms"),
    [
        (datetime(2026, 5, 4, 14, 30, 15, tzinfo=UTC), (14, 30, 15)),
        (datetime(2026, 5, 4, 14, 30, 15, tzinfo=timezone(timedelta(hours=2))), (12, 30, 15)),
        (datetime(2026, 5, 4, 0, 10, 0, tzinfo=timezone(timedelta(hours=-5))), (5, 10, 0)),
        ("2026-05-04T23:59:59-01:00", (0, 59, 59)),
        (datetime(2026, 5, 4, 14, 30, 15), (14, 30, 15)),  # naive: taken as UTC
    ],
)
def test_start_barrier_waits_until_the_utc_time_of_day(curved_plan, given, hms):
    options = MissionOptions(start_time_utc=given)
    for mission in build_missions(curved_plan, options):
        delay = mission.items[3]
        assert delay.command == MavCmd.NAV_DELAY and delay.frame == MavFrame.MISSION
        assert (delay.param1, delay.param2, delay.param3, delay.param4) == (-1.0, *hms)


@pytest.fixture
def new_york_local_time(monkeypatch):
    """Run with a local time zone far from UTC, so that naive times would show."""
    monkeypatch.setenv("TZ", "America/New_York")
    time.tzset()
    yield
    monkeypatch.undo()
    time.tzset()


@pytest.mark.usefixtures("new_york_local_time")
def test_start_time_is_an_instant_in_utc_whatever_the_local_zone():
    naive = MissionOptions(start_time_utc=datetime(2026, 5, 4, 14, 30, 15))
    aware = MissionOptions(start_time_utc="2026-05-04T16:30:15+02:00")
    epoch = (datetime(2026, 5, 4, 14, 30, 15) - datetime(1970, 1, 1)).total_seconds()
    assert naive.start_time_utc.timestamp() == aware.start_time_utc.timestamp() == epoch


def test_land_at_the_end_when_asked(curved_plan):
    for mission in build_missions(curved_plan, MissionOptions(end="land")):
        last = mission.items[-1]
        assert last.command == MavCmd.NAV_LAND
        assert (last.x, last.y) == (mission.items[-2].x, mission.items[-2].y)


def test_slow_legs_are_the_horizontal_speeds_arducopter_ignores():
    # 0.5 m in 10 s: 5 cm/s, below ArduCopter's 10 cm/s minimum; then 1 m in 4 s.
    plan = hand_made_plan([[0.5, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]], [10.0, 4.0, 4.0])
    assert LegSpeeds.of(plan).slow_legs() == [(1, 1), (2, 1), (3, 1)]
