"""Mission items against the plan they encode: the legs the items describe take the planned time."""

from __future__ import annotations

import numpy as np
import pytest

from missions.builder import CLIMB_SPEED, GROUND_SPEED, build_missions
from missions.geodesy import DEGREE_UNIT, ardupilot_altitude, enu_from_geodetic
from missions.items import MavCmd
from missions.options import MissionOptions
from missions.waypoints import WaypointPlan


def test_speed_items_fit_the_encoded_waypoints_of_near_vertical_legs():
    """A 5 m climb drifting 3 cm sideways: rounding to 1e-7 degree (about 1 cm) changes the
    sideways run by a third, so a ground speed computed from the unrounded run makes the
    leg's ground limit too low or too high; the autopilot flies the rounded waypoints."""
    options = MissionOptions()
    start = np.array([[0.0, 0.0, 2.0], [1.0, 0.0, 2.0], [0.0, 1.0, 2.0]])
    drift = np.array([0.0173, 0.0306, 0.0])  # chosen to round far from the true run
    plan = WaypointPlan(
        ok=True,
        indices=np.arange(2),
        time=np.array([0.0, 10.0]),
        q=np.zeros((2, 9)),
        drones=np.stack([start, start + drift + [0.0, 0.0, 5.0]]),
        max_platform_deviation=0.0,
        max_cable_length_error=0.0,
    )
    rounding = []
    for mission in build_missions(plan, options):
        by_type = {
            int(i.param1): i.param2 for i in mission.items if i.command == MavCmd.DO_CHANGE_SPEED
        }
        waypoints = [i for i in mission.items if i.command == MavCmd.NAV_WAYPOINT][1:]
        ends = np.array(
            [
                enu_from_geodetic(
                    i.x * DEGREE_UNIT,
                    i.y * DEGREE_UNIT,
                    i.z + options.origin.altitude,
                    options.origin,
                )
                for i in waypoints
            ]
        )
        run = float(np.linalg.norm(ends[1, :2] - ends[0, :2]))
        rounding.append(abs(run - float(np.linalg.norm(drift[:2]))))
        assert by_type[GROUND_SPEED] * 10.0 == pytest.approx(run, rel=1e-6)
        assert by_type[CLIMB_SPEED] * 10.0 == pytest.approx(5.0, rel=1e-6)
    assert max(rounding) > 0.003  # rounding changed a sideways run by more than 10 %


def test_climb_speeds_fit_the_centimetres_ardupilot_stores():
    """A 2 m level leg rising 1.6 cm: ArduPilot keeps 2.026 m and 2.042 m as 2.02 and 2.04 m,
    so the climb is 2 cm, not 1.6; a climb limit for 1.6 cm would stretch the leg by 25 %."""
    options = MissionOptions()
    start = np.array([[0.0, 0.0, 2.026], [1.0, 0.0, 2.026], [0.0, 1.0, 2.026]])
    plan = WaypointPlan(
        ok=True,
        indices=np.arange(2),
        time=np.array([0.0, 10.0]),
        q=np.zeros((2, 9)),
        drones=np.stack([start, start + np.array([2.0, 0.0, 0.016])]),
        max_platform_deviation=0.0,
        max_cable_length_error=0.0,
    )
    assert ardupilot_altitude([2.026, 2.042]) == pytest.approx([2.02, 2.04])
    for mission in build_missions(plan, options):
        climb = [
            i.param2
            for i in mission.items
            if i.command == MavCmd.DO_CHANGE_SPEED and i.param1 == CLIMB_SPEED
        ]
        waypoints = [i for i in mission.items if i.command == MavCmd.NAV_WAYPOINT][1:]
        run = float(np.diff(ardupilot_altitude([w.z for w in waypoints]))[0])
        # ENU "up" bends with the earth: 0.3 um over the 2 m leg
        assert climb[0] * 10.0 == pytest.approx(run, abs=1e-6)
        assert run == pytest.approx(0.02)
