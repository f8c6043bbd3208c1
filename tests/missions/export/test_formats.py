"""Mission files: golden ``.waypoints`` and ``.plan``, pymavlink's reader, JSON round trip.

The golden files under ``golden/`` are the missions of a tiny fixed plan (hover at 5 m,
1 m east at a ground speed of 0.25 m/s, then 1 m up at a climb speed of 0.2 m/s, each
limit binding on its leg and the others at ArduCopter's defaults). Besides the
byte-for-byte comparison, their content is checked against values written by hand here
(speeds, commands, frames, altitudes) and against a first-order WGS84 conversion, so the
golden files are evidence, not snapshots.
Regenerate them with ``FLYCRANE_UPDATE_GOLDEN=1`` only after checking the difference.
"""

from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np
import pytest
from pymavlink import mavwp

from missions.autopilots.spline import SpeedLimits
from missions.export.builder import build_missions
from missions.export.formats import dumps, mission_from_json, mission_json, qgc_plan, waypoints_text
from missions.export.items import MavCmd, MavFrame
from missions.options import MissionOptions
from tests.missions.helpers import approximate_geodetic, hand_made_flight

GOLDEN = Path(__file__).parent / "golden"
UPDATE = os.environ.get("FLYCRANE_UPDATE_GOLDEN") == "1"

TINY_LIMITS = [SpeedLimits(0.25, 2.5, 1.5), SpeedLimits(5.0, 0.2, 1.5)]
TINY = hand_made_flight([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0]], TINY_LIMITS)
OPTIONS = MissionOptions()

# Hand-written content of every drone's tiny mission: (command, file frame, param1, param2).
TINY_ITEMS = [
    (16, 0, 0.0, 0.0),  # home, AMSL
    (22, 3, 0.0, 0.0),  # takeoff to the start altitude, relative
    (17, 3, 0.0, 0.0),  # hold at the start until released
    (178, 2, 1.0, 0.25),  # ground speed 0.25 m/s (ArduCopter's default WPNAV_SPEED before)
    (82, 3, 0.0, 0.0),  # 1 m east
    (178, 2, 1.0, 5.0),  # ground speed back to the generous default
    (178, 2, 2.0, 0.2),  # climb speed 0.2 m/s
    (82, 3, 0.0, 0.0),  # 1 m up
    (17, 3, 0.0, 0.0),  # hold at the end
]


@pytest.fixture(scope="module")
def tiny_missions():
    return build_missions(TINY, OPTIONS)


def compare_with_golden(name: str, text: str) -> None:
    path = GOLDEN / name
    if UPDATE:
        path.parent.mkdir(exist_ok=True)
        path.write_text(text, encoding="utf-8")
    assert text == path.read_text(encoding="utf-8"), f"{name} differs from its golden file"


@pytest.mark.parametrize("drone", [1, 2, 3])
def test_waypoints_file_matches_its_golden_file(tiny_missions, drone):
    compare_with_golden(f"tiny_drone{drone}.waypoints", waypoints_text(tiny_missions[drone - 1]))


def test_plan_file_matches_its_golden_file(tiny_missions):
    text = dumps(qgc_plan(tiny_missions[0], OPTIONS.max_drone_speed))
    compare_with_golden("tiny_drone1.plan", text)


@pytest.mark.parametrize("drone", [1, 2, 3])
def test_golden_waypoints_file_says_what_the_plan_says(drone):
    """Read the golden file with nothing but str.split and check it against the plan."""
    lines = (GOLDEN / f"tiny_drone{drone}.waypoints").read_text(encoding="utf-8").splitlines()
    assert lines[0] == "QGC WPL 110"
    rows = [line.split("\t") for line in lines[1:]]
    assert all(len(row) == 12 for row in rows)
    assert [int(r[0]) for r in rows] == list(range(len(TINY_ITEMS)))
    assert [int(r[1]) for r in rows] == [1] + [0] * (len(TINY_ITEMS) - 1)  # home: "current"
    assert [(int(r[3]), int(r[2]), float(r[4])) for r in rows] == [t[:3] for t in TINY_ITEMS]
    for row, expected in zip(rows, TINY_ITEMS, strict=True):
        assert float(row[5]) == pytest.approx(expected[3], rel=1e-7)
    assert all(float(r[6]) == (-1.0 if int(r[3]) == 178 else 0.0) for r in rows)
    assert all(int(r[11]) == 1 for r in rows)
    start, east, up = TINY.drones[:, drone - 1]
    np.testing.assert_allclose(east - start, [1, 0, 0], atol=1e-12)
    np.testing.assert_allclose(up - east, [0, 0, 1], atol=1e-12)
    # home below the start, then start (takeoff, hold), east, up, up (hold)
    points = [start * [1, 1, 0], start, start, east, up, up]
    rows_with_position = [r for r in rows if int(r[3]) != 178]
    lat, lon = approximate_geodetic(np.array(points), OPTIONS.origin)
    for row, la, lo, point in zip(rows_with_position, lat, lon, points, strict=True):
        assert float(row[8]) == pytest.approx(la, abs=0.51e-7)
        assert float(row[9]) == pytest.approx(lo, abs=0.51e-7)
        if row is rows[0]:
            assert float(row[10]) == pytest.approx(OPTIONS.origin.altitude, abs=1e-6)
        else:  # the centimetre ArduPilot stores it as (int32 of float32 z times 100),
            # above home: where the drone stood, home_height above the ground
            stored = int(np.float32(float(row[10])) * np.float32(100.0))
            assert stored == round((point[2] - OPTIONS.home_height) * 100)


def test_golden_plan_file_says_what_the_plan_says():
    plan = json.loads((GOLDEN / "tiny_drone1.plan").read_text(encoding="utf-8"))
    assert plan["fileType"] == "Plan"
    mission = plan["mission"]
    assert (mission["firmwareType"], mission["vehicleType"], mission["version"]) == (3, 2, 2)
    assert mission["cruiseSpeed"] == mission["hoverSpeed"] == 0.5
    home = mission["plannedHomePosition"]
    lat, lon = approximate_geodetic(TINY.drones[0, 0] * [1, 1, 0], OPTIONS.origin)
    assert home == [
        pytest.approx(lat, abs=0.51e-7),
        pytest.approx(lon, abs=0.51e-7),
        pytest.approx(488.0, abs=1e-5),
    ]
    items = mission["items"]
    assert [(it["command"], it["frame"], it["params"][0]) for it in items] == [
        t[:3] for t in TINY_ITEMS[1:]
    ]
    for it, expected in zip(items, TINY_ITEMS[1:], strict=True):
        assert it["params"][1] == pytest.approx(expected[3], rel=1e-7)
    assert [it["doJumpId"] for it in items] == list(range(1, len(TINY_ITEMS)))
    for item in items:
        assert item["type"] == "SimpleItem" and item["autoContinue"] is True
        assert len(item["params"]) == 7
        if item["frame"] == MavFrame.GLOBAL_RELATIVE_ALT:
            assert item["AltitudeMode"] == 1  # QGC: relative to home
            assert item["Altitude"] == pytest.approx(item["params"][6], abs=1e-8)
        else:
            assert "Altitude" not in item  # DO_ commands carry no position


def assert_loaded_like(loader, mission):
    assert loader.count() == len(mission.items)
    for item in mission.items:
        w = loader.wp(item.seq)
        assert (w.seq, w.command, w.autocontinue) == (item.seq, item.command, item.autocontinue)
        expected_frame = {MavFrame.GLOBAL_INT: 0, MavFrame.GLOBAL_RELATIVE_ALT_INT: 3}.get(
            item.frame, item.frame
        )
        assert w.frame == expected_frame
        assert w.current == (1 if item.seq == 0 else 0)
        for ours, theirs in zip((item.param1, item.param2, item.param3, item.param4),
                                (w.param1, w.param2, w.param3, w.param4), strict=True):  # fmt: skip
            assert theirs == pytest.approx(ours, abs=1e-8)
        assert abs(w.x - item.x * 1e-7) < 1e-7 and round(w.x * 1e7) == item.x
        assert abs(w.y - item.y * 1e-7) < 1e-7 and round(w.y * 1e7) == item.y
        assert w.z == pytest.approx(item.z, abs=1e-6)


@pytest.mark.parametrize("which", ["tiny", "curved", "curved amsl"])
def test_pymavlink_reads_back_every_item_of_the_waypoints_files(
    tmp_path, tiny_missions, curved_flight, which
):
    if which == "tiny":
        missions = tiny_missions
    else:
        amsl = which.endswith("amsl")
        options = MissionOptions(altitude_frame="amsl") if amsl else MissionOptions()
        missions = build_missions(curved_flight, options)
    for mission in missions:
        path = tmp_path / f"drone{mission.drone}.waypoints"
        path.write_text(waypoints_text(mission), encoding="utf-8")
        loader = mavwp.MAVWPLoader()
        assert loader.load(str(path)) == len(mission.items)
        assert_loaded_like(loader, mission)


@pytest.mark.parametrize(
    "options",
    [MissionOptions(), MissionOptions(altitude_frame="amsl", end="land")],
    ids=["defaults", "amsl, land"],
)
def test_mission_json_round_trips_every_field(curved_flight, options):
    for mission in build_missions(curved_flight, options):
        text = dumps(mission_json(mission))
        back = mission_from_json(json.loads(text))
        assert back == mission
        assert all(type(it.x) is int and type(it.y) is int for it in back.items)
        assert [int(it.frame) for it in back.items] == [int(it.frame) for it in mission.items]


def test_plan_items_carry_the_mission_items(curved_flight):
    for mission in build_missions(curved_flight, MissionOptions()):
        plan = json.loads(dumps(qgc_plan(mission, 0.5)))
        home, rest = mission.items[0], mission.items[1:]
        assert plan["mission"]["plannedHomePosition"][2] == home.z
        assert len(plan["mission"]["items"]) == len(rest)
        for entry, item in zip(plan["mission"]["items"], rest, strict=True):
            assert entry["command"] == item.command and entry["doJumpId"] == item.seq
            assert round(entry["params"][4] * 1e7) == item.x
            assert round(entry["params"][5] * 1e7) == item.y
            assert entry["params"][6] == pytest.approx(item.z, abs=1e-8)
        assert {it.command for it in rest} >= {MavCmd.NAV_TAKEOFF, MavCmd.NAV_LOITER_UNLIM}
