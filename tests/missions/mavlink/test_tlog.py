"""The tlog's clock: wall time stretched by the simulators' speed-up, piecewise where they
change pace (analytic values)."""

from __future__ import annotations

import pytest

from missions.mavlink.tlog import StretchedClock


def test_a_change_of_pace_keeps_the_time_and_changes_its_rate():
    clock = StretchedClock(5.0, 1000.0, 10.0)
    assert clock.at(12.0) == pytest.approx(1010.0)  # 2 s of wall time at x5
    clock.change_pace(2.0, 12.0)
    assert clock.speedup == 2.0
    assert clock.at(12.0) == pytest.approx(1010.0)  # no jump at the change
    assert clock.at(15.0) == pytest.approx(1016.0)  # 3 s of wall time at x2
