"""What ArduCopter does with the DO_CHANGE_SPEED items before a spline leg, against what the
Rescue SITL flight recorded (``tests/missions/data/README.md``)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from missions.autopilots.ardupilot import changed_limits, limits_at_setup
from missions.autopilots.spline import AccelLimits, HermiteLeg, SpeedLimits, entry_speed_limit
from missions.export.items import MavCmd
from missions.geodesy import DEGREE_UNIT, ardupilot_altitude, enu_from_geodetic
from missions.options import GeodeticOrigin

DATA = Path(__file__).parents[1] / "data" / "sitl_leg_times.json"
#: Rescue drone 1's desired speed 8 ms before its last leg started (78.479 s; the leg at
#: 78.4869 s), braking at 1 m/s^2: PSCN/PSCE/PSCD DVN, DVE, DVD of its DataFlash log
#: (``f_rescue_v3/sitl/sitl0/logs/00000001.BIN``) [m/s].
SITL_SPEED_INTO_LAST_LEG = 0.193


def test_only_the_first_changed_limit_is_in_force_when_a_leg_is_set_up():
    before, after = SpeedLimits(5.0, 2.5, 0.1), SpeedLimits(0.3, 2.5, 1.5)
    assert changed_limits(before, after) == ("horizontal", "down")
    assert limits_at_setup(before, after) == SpeedLimits(0.3, 2.5, 0.1)
    assert limits_at_setup(after, after) == after
    # below the float32 precision the builder sends no item: nothing changes then
    assert changed_limits(after, SpeedLimits(0.3 * (1 + 1e-8), 2.5, 1.5)) == ()


def test_a_leg_ends_at_the_next_legs_entry_limit_under_the_limits_at_its_setup():
    """Rescue drone 1, leg 12 (DO ground 0.325 then DO descent 1.5, after a leg at descent
    0.102) into leg 13: SITL left leg 12 at the speed the old descent limit allows at leg
    13's start, not at the one the new limit would."""
    rows = json.loads(DATA.read_text(encoding="utf-8"))["flights"][0]["drones"][0]["mission"]
    home = rows[0]
    origin = GeodeticOrigin(latitude=home[6] * DEGREE_UNIT, longitude=home[7] * DEGREE_UNIT,
                            altitude=home[8])  # fmt: skip
    splines = [r for r in rows if r[1] == MavCmd.NAV_SPLINE_WAYPOINT]
    p11, p12, p13 = (
        enu_from_geodetic(
            np.array([r[6] * DEGREE_UNIT]), np.array([r[7] * DEGREE_UNIT]),
            np.array([home[8] + float(ardupilot_altitude(r[8]))]), origin,
        )[0]
        for r in splines[-3:]
    )  # fmt: skip
    last = HermiteLeg.between(p12, p13, p13 - p11, np.zeros(3))  # a stop at the end
    accel = AccelLimits(2.0, 2.0)  # the flight's WPNAV_ACCEL, _ACCEL_Z
    leg11, leg12 = SpeedLimits(5.0, 2.5, 0.10206093), SpeedLimits(0.32514183, 2.5, 1.5)
    at_setup = entry_speed_limit(last, limits_at_setup(leg11, leg12), accel)
    with_all = entry_speed_limit(last, leg12, accel)
    assert at_setup == pytest.approx(SITL_SPEED_INTO_LAST_LEG, rel=0.1)
    assert with_all > 2 * SITL_SPEED_INTO_LAST_LEG
