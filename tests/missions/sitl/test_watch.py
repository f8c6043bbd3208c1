"""Watching the drones at their start hold: steady, how long at an item, how far off at
worst, and the release judged against the position-error model where wind keeps a drone
from ever holding steady (no simulator: messages as the vehicles send them)."""

from __future__ import annotations

import math
from types import SimpleNamespace

from missions.export.items import MavCmd, MavFrame, MissionItem
from missions.position_error import PRESETS
from missions.sitl.watch import HoldWatch

HOLD = MissionItem(seq=2, frame=MavFrame.GLOBAL_RELATIVE_ALT_INT, command=MavCmd.NAV_LOITER_UNLIM,
                   x=473977000, y=85456000, z=5.0)  # fmt: skip
#: metres per 1e-7 degree of latitude (WGS-84 near 47 deg N)
NORTH_PER_UNIT = 0.011131


class _Link:
    def __init__(self, name: str) -> None:
        self.name = name
        self.listeners: list = []

    def add_listener(self, types: tuple[str, ...], listener) -> None:
        self.listeners.append(listener)

    def send(self, msg: SimpleNamespace) -> None:
        for listener in self.listeners:
            listener(msg)


def _at(t: float, north: float = 0.0, up: float = 0.0, speed: float = 0.0) -> SimpleNamespace:
    """A GLOBAL_POSITION_INT ``north`` and ``up`` [m] from the hold at boot time ``t``
    (north in whole 1e-7 degrees, 1.1 cm, as the message carries it)."""
    return SimpleNamespace(
        get_type=lambda: "GLOBAL_POSITION_INT", time_boot_ms=round(t * 1000),
        lat=HOLD.x + round(north / NORTH_PER_UNIT), lon=HOLD.y,
        relative_alt=round((HOLD.z + up) * 1000), vx=round(speed * 100), vy=0, vz=0,
    )  # fmt: skip


def _current(seq: int) -> SimpleNamespace:
    return SimpleNamespace(get_type=lambda: "MISSION_CURRENT", seq=seq)


def _watch() -> tuple[HoldWatch, _Link]:
    link = _Link("drone1")
    watch = HoldWatch([link], [HOLD], settle_speed=0.05, settle_distance=0.02, window_s=3.0)
    return watch, link


def test_a_drone_is_steady_once_slow_and_near_its_hold_and_not_after_a_gust():
    watch, link = _watch()
    link.send(_at(9.0, north=1.0, speed=1.0))
    link.send(_current(2))
    for t in (10.0, 11.0, 12.0, 13.5):
        link.send(_at(t, north=0.01, up=-0.01, speed=0.02))
    assert math.isclose(watch.steady_for("drone1"), 3.5)
    assert math.isclose(watch.at_current_for("drone1"), 4.5)
    link.send(_at(14.0, north=0.05, speed=0.3))
    assert watch.steady_for("drone1") == 0.0
    speed, across, vertical = watch.worst("drone1")
    assert math.isclose(speed, 0.3) and math.isclose(across, 0.05, abs_tol=0.006)
    assert math.isclose(vertical, 0.01, abs_tol=0.001)


def test_the_worst_is_over_the_last_window_only():
    watch, link = _watch()
    link.send(_current(2))
    link.send(_at(10.0, north=0.5, speed=0.5))
    for t in (11.0, 12.0, 13.0, 14.0):
        link.send(_at(t, north=0.03, speed=0.1))
    speed, across, _ = watch.worst("drone1")
    assert math.isclose(speed, 0.1) and math.isclose(across, 0.03, abs_tol=0.006)


def test_an_unsteady_hold_is_released_within_the_model_and_refused_beyond_it():
    """The ``sitl`` model: 7 cm across (4 common + 3 relative), 6 cm up or down."""
    model = PRESETS["sitl"]
    for up, refused in ((0.05, False), (0.08, True)):
        watch, link = _watch()
        link.send(_current(2))
        for t in (10.0, 11.0, 12.0, 13.0):
            link.send(_at(t, north=0.04, up=up if t == 12.0 else 0.0, speed=0.12))
        reasons = watch.unsteady_reasons(model, 300.0, 3.0)
        assert bool(reasons) == refused
        if refused:
            assert reasons[0].startswith("drone1: not steady") and "0.080 m up" in reasons[0]


def test_a_steady_hold_has_nothing_to_say():
    watch, link = _watch()
    link.send(_current(2))
    for t in (10.0, 11.0, 12.0, 13.5):
        link.send(_at(t, north=0.01, speed=0.01))
    assert watch.unsteady_reasons(PRESETS["sitl"], 300.0, 3.0) == ()
