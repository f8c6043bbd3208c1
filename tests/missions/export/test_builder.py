"""Mission items against the flight plan they encode.

The speed items are read back with a DO_CHANGE_SPEED state machine written from
ArduCopter's rules (:func:`tests.missions.helpers.applied_limits`), positions with a
first-order WGS84 conversion (:func:`tests.missions.helpers.approximate_geodetic`).
"""

from __future__ import annotations

import numpy as np
import pytest

from missions.autopilots.spline import SpeedLimits
from missions.export.builder import HOLD_SEQ, RELEASE_SEQ, build_missions
from missions.export.items import MavCmd, MavFrame
from missions.options import MissionOptions
from tests.missions.helpers import applied_limits, approximate_geodetic, hand_made_flight

OPTIONS = MissionOptions()


@pytest.fixture(scope="module")
def missions(curved_flight):
    return build_missions(curved_flight, OPTIONS)


def test_every_drone_holds_at_the_start_then_flies_one_spline_leg_per_leg(curved_flight, missions):
    legs = len(curved_flight.time) - 1
    for mission in missions:
        commands = [int(it.command) for it in mission.items]
        assert commands[:3] == [MavCmd.NAV_WAYPOINT, MavCmd.NAV_TAKEOFF, MavCmd.NAV_LOITER_UNLIM]
        assert commands[HOLD_SEQ] == MavCmd.NAV_LOITER_UNLIM and RELEASE_SEQ == HOLD_SEQ + 1
        assert commands[-1] == MavCmd.NAV_LOITER_UNLIM
        middle = commands[RELEASE_SEQ:-1]
        assert set(middle) <= {MavCmd.DO_CHANGE_SPEED, MavCmd.NAV_SPLINE_WAYPOINT}
        assert middle.count(MavCmd.NAV_SPLINE_WAYPOINT) == legs
        assert middle[-1] == MavCmd.NAV_SPLINE_WAYPOINT
        assert MavCmd.NAV_DELAY not in commands  # never next to a spline (builder docstring)


def test_speed_items_give_each_leg_its_planned_limits_and_nothing_more(curved_flight, missions):
    initial = curved_flight.settings.initial_speeds
    for j, mission in enumerate(missions):
        assert applied_limits(mission, initial) == list(curved_flight.limits[j])
        # every item changes a limit: none is redundant
        state = {1: initial.horizontal, 2: initial.up, 3: initial.down}
        for item in mission.items:
            if item.command == MavCmd.DO_CHANGE_SPEED:
                assert state[int(item.param1)] != item.param2
                state[int(item.param1)] = item.param2


def test_home_is_on_the_ground_below_each_drone_start(curved_flight, missions):
    for j, mission in enumerate(missions):
        home = mission.items[0]
        assert home.frame == MavFrame.GLOBAL_INT
        assert home.z == pytest.approx(OPTIONS.origin.altitude, abs=1e-6)  # ground, AMSL
        lat, lon = approximate_geodetic(curved_flight.drones[0, j], OPTIONS.origin)
        assert abs(home.x - lat * 1e7) <= 0.51 and abs(home.y - lon * 1e7) <= 0.51


def stored_centimetres(z: float) -> int:
    """AP_Mission's ``Location::alt`` of a MISSION_ITEM_INT ``z``: ``packet.z * 100.0f``,
    a float32 product converted to int32 (truncated)."""
    return int(np.float32(z) * np.float32(100.0))


def test_positions_are_the_plans_stored_waypoints(curved_flight, missions):
    for j, mission in enumerate(missions):
        located = [it for it in mission.items[1:] if it.command != MavCmd.DO_CHANGE_SPEED]
        # takeoff and hold at the first waypoint, the splines, the final hold at the last
        points = [
            curved_flight.drones[0, j],
            *curved_flight.drones[:, j],
            curved_flight.drones[-1, j],
        ]
        assert len(located) == len(points)
        for item, enu in zip(located, points, strict=True):
            lat, lon = approximate_geodetic(enu, OPTIONS.origin)
            assert abs(item.x - lat * 1e7) <= 0.51 and abs(item.y - lon * 1e7) <= 0.51
            # what the plan flies, above home: where the drone stood, home_height up
            assert stored_centimetres(item.z) == round((enu[2] - OPTIONS.home_height) * 100)
            assert item.frame == MavFrame.GLOBAL_RELATIVE_ALT_INT


def test_amsl_altitudes_add_the_origin_altitude(curved_flight):
    (mission,) = build_missions(curved_flight, MissionOptions(altitude_frame="amsl"))[:1]
    spline = next(it for it in mission.items if it.command == MavCmd.NAV_SPLINE_WAYPOINT)
    assert spline.frame == MavFrame.GLOBAL_INT
    assert stored_centimetres(spline.z) == round(
        (OPTIONS.origin.altitude + curved_flight.drones[1, 0, 2]) * 100
    )


def test_land_at_the_end_when_asked(curved_flight):
    for mission in build_missions(curved_flight, MissionOptions(end="land")):
        assert mission.items[-1].command == MavCmd.NAV_LAND


def test_a_limit_that_stays_is_not_sent_again():
    """Three legs east at one ground speed: one DO_CHANGE_SPEED, before the first."""
    east = SpeedLimits(0.3, 2.5, 1.5)
    plan = hand_made_flight([[1.0, 0.0, 0.0]] * 3, [east] * 3)
    for mission in build_missions(plan, OPTIONS):
        speeds = [it for it in mission.items if it.command == MavCmd.DO_CHANGE_SPEED]
        assert [(it.param1, it.param2) for it in speeds] == [(1.0, 0.3)]
        assert mission.items[RELEASE_SEQ] is speeds[0] or mission.items[RELEASE_SEQ] == speeds[0]


def test_the_release_lands_on_the_first_legs_speed_items():
    """MISSION_SET_CURRENT to RELEASE_SEQ must run the first leg's DO items (ArduCopter runs
    the DO items from the new seq up to the next nav item; aimed at the spline, they would be
    skipped)."""
    plan = hand_made_flight([[1.0, 0.0, 0.0]], [SpeedLimits(0.3, 0.4, 1.5)])
    for mission in build_missions(plan, OPTIONS):
        first = mission.items[RELEASE_SEQ : RELEASE_SEQ + 2]
        assert [int(it.command) for it in first] == [MavCmd.DO_CHANGE_SPEED] * 2
        assert np.isclose(sorted(it.param2 for it in first), [0.3, 0.4]).all()
