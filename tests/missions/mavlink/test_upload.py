"""Upload and read-back verification against mock ArduCopters over loopback UDP."""

from __future__ import annotations

import math
import time
from dataclasses import replace

import pytest

from missions.export.items import MavCmd, MavFrame, MissionItem
from missions.mavlink.errors import FleetError, MissionTransferError, MissionVerificationError
from missions.mavlink.fleet import Fleet, upload_to_vehicles
from missions.mavlink.messages import ardupilot_readback, as_sent, float32, item_difference
from missions.mavlink.transfer import download_mission
from missions.mavlink.transport import VehicleLink
from missions.mavlink.upload import Verification, upload_and_verify, verify_mission
from missions.mock.autopilot import MockConfig
from missions.mock.sim_clock import SimClock
from tests.missions.loopback import HOME, waypoint_mission


def comparable(items):
    """Items as plain tuples with NaN made comparable (dataclass equality has NaN != NaN)."""

    def norm(v):
        return "nan" if isinstance(v, float) and math.isnan(v) else v

    return [tuple(norm(getattr(i, f)) for f in i.__dataclass_fields__) for i in items]


def test_three_vehicles_upload_concurrently_and_hold_exactly_the_missions(spawn_mock, fast_policy):
    clock = SimClock(speedup=5.0)
    spawned = [spawn_mock(MockConfig(system_id=k, home=HOME), clock) for k in (1, 2, 3)]
    missions = [waypoint_mission(drone, 40) for drone in (1, 2, 3)]
    with Fleet.connect([a for _, a in spawned], fast_policy, names=["d1", "d2", "d3"]) as fleet:
        reports = fleet.upload(missions)
    for (mock, _), mission, report in zip(spawned, missions, reports, strict=True):
        assert report.item_count == len(mission.items) == 42
        assert report.system_id == mock.own.system
        # what the vehicle stored, independent of the client's own read-back comparison
        stored = mock.mission
        assert comparable(stored[1:]) == comparable(as_sent(i) for i in mission.items[1:])
        # seq 0 reads back as the vehicle's home (ArduPilot), not as uploaded
        assert (report.home.frame, report.home.command) == (MavFrame.GLOBAL, MavCmd.NAV_WAYPOINT)
        assert (report.home.x, report.home.y) == (
            round(HOME.lat_deg * 1e7),
            round(HOME.lon_deg * 1e7),
        )
        assert report.home.z == pytest.approx(HOME.alt_m)


@pytest.mark.parametrize(
    ("request_int", "expected"), [(False, "MISSION_REQUEST"), (True, "MISSION_REQUEST_INT")]
)
def test_both_request_kinds_are_answered(spawn_mock, fast_policy, request_int, expected):
    _, address = spawn_mock(MockConfig(home=HOME, request_int=request_int))
    seen = []
    with VehicleLink(address, fast_policy) as link:
        link.add_listener(
            ("MISSION_REQUEST", "MISSION_REQUEST_INT"), lambda msg: seen.append(msg.get_type())
        )
        link.wait_heartbeat()
        report = upload_and_verify(link, waypoint_mission(1, 5), fast_policy)
    assert report.item_count == 7
    assert set(seen) == {expected} and len(seen) >= 7


def test_no_space_while_booting_is_retried_until_accepted(spawn_mock, fast_policy):
    # 2 simulated seconds of boot at speed-up 5: 0.4 s of NO_SPACE answers
    mock, address = spawn_mock(MockConfig(home=HOME, boot_no_space_s=2.0), SimClock(5.0))
    acks = []
    with VehicleLink(address, fast_policy) as link:
        link.add_listener(("MISSION_ACK",), lambda msg: acks.append(msg.type))
        link.wait_heartbeat()
        upload_and_verify(link, waypoint_mission(1, 3), fast_policy)
    assert acks.count(4) >= 2  # MAV_MISSION_NO_SPACE, answered at least twice
    assert acks[-1] == 0 and len(mock.mission) == 5


def test_no_space_is_final_after_the_retry_window(spawn_mock, fast_policy):
    _, address = spawn_mock(MockConfig(home=HOME, max_items=10))
    policy = type(fast_policy)(**{**fast_policy.__dict__, "no_space_retry_s": 0.5})
    with VehicleLink(address, policy, name="small") as link:
        link.wait_heartbeat()
        started = time.monotonic()
        with pytest.raises(MissionTransferError) as error:
            upload_and_verify(link, waypoint_mission(1, 10), policy)
    assert time.monotonic() - started >= 0.5
    assert (error.value.vehicle, error.value.operation) == ("small", "upload")
    assert (error.value.result, error.value.result_name) == (4, "MAV_MISSION_NO_SPACE")


def test_fleet_reports_every_vehicle_and_the_ones_that_worked(spawn_mock, fast_policy):
    _, ok = spawn_mock(MockConfig(system_id=1, home=HOME))
    _, full = spawn_mock(MockConfig(system_id=2, home=HOME, max_items=3))
    policy = type(fast_policy)(**{**fast_policy.__dict__, "no_space_retry_s": 0.0})
    with pytest.raises(FleetError) as error:
        upload_to_vehicles([ok, full], [waypoint_mission(1, 2), waypoint_mission(2, 2)], policy)
    assert error.value.succeeded == (ok,)
    assert isinstance(error.value.failures[full], MissionTransferError)
    assert error.value.failures[full].result_name == "MAV_MISSION_NO_SPACE"


def test_read_back_matches_what_the_mock_stored(spawn_mock, fast_policy):
    mock, address = spawn_mock()
    with VehicleLink(address, fast_policy) as link:
        link.wait_heartbeat()
        upload_and_verify(link, waypoint_mission(1, 4), fast_policy, Verification.NONE)
        downloaded = download_mission(link, fast_policy)
    assert comparable(downloaded) == comparable(mock.mission)


def test_verification_names_the_first_difference():
    sent = waypoint_mission(1, 3).items
    back = list(as_sent(i) for i in sent)
    verify_mission("v", sent, back, Verification.ARDUPILOT)
    back[0] = MissionItem(0, MavFrame.GLOBAL, MavCmd.NAV_WAYPOINT, x=1, y=2, z=600.0)
    verify_mission("v", sent, back, Verification.ARDUPILOT)  # seq 0 is the vehicle's home
    with pytest.raises(MissionVerificationError) as error:
        verify_mission("v", sent, back, Verification.ALL_ITEMS)
    assert (error.value.seq, error.value.field) == (0, "frame")
    back[3] = back[3].__class__(**{**back[3].__dict__, "y": back[3].y + 1})
    with pytest.raises(MissionVerificationError) as error:
        verify_mission("v", sent, back, Verification.ARDUPILOT)
    assert (error.value.vehicle, error.value.seq, error.value.field) == ("v", 3, "y")
    assert error.value.actual - error.value.expected == 1
    with pytest.raises(MissionVerificationError) as error:
        verify_mission("v", sent, back[:-1], Verification.ARDUPILOT)
    assert (error.value.seq, error.value.field, error.value.expected, error.value.actual) == (
        None,
        "count",
        5,
        4,
    )


def test_ardupilot_verification_accepts_what_arducopter_stores():
    """ArduCopter reads altitudes back in whole centimetres and NAV_WAYPOINT without its
    acceptance radius (AP_Mission): a faithful upload, not a failed one."""
    sent = waypoint_mission(1, 3).items  # altitudes 5.123 m apart, param2 = 1.5
    back = [ardupilot_readback(i) for i in sent]
    assert float32(back[3].z) != float32(sent[3].z) and back[3].param2 == 0.0
    verify_mission("v", sent, back, Verification.ARDUPILOT)
    with pytest.raises(MissionVerificationError):
        verify_mission("v", sent, back, Verification.ALL_ITEMS)
    back[3] = replace(back[3], z=back[3].z + 0.01)  # a centimetre off: a different mission
    with pytest.raises(MissionVerificationError) as error:
        verify_mission("v", sent, back, Verification.ARDUPILOT)
    assert (error.value.seq, error.value.field) == (3, "z")


def test_do_items_read_back_in_frame_global_and_the_upload_verifies(spawn_mock, fast_policy):
    """ArduCopter 4.5.7 returns a DO command sent in frame MISSION in frame GLOBAL (0);
    the mock too, so that the verification takes the same path against both."""
    mission = waypoint_mission(1, 2)
    speed = MissionItem(4, MavFrame.MISSION, MavCmd.DO_CHANGE_SPEED, param1=1, param2=0.5)
    mission = type(mission)(1, (*mission.items, speed))
    mock, address = spawn_mock()
    with VehicleLink(address, fast_policy) as link:
        link.wait_heartbeat()
        upload_and_verify(link, mission, fast_policy)
        back = download_mission(link, fast_policy)
    assert back[4].frame == MavFrame.GLOBAL and mock.mission[4].frame == MavFrame.GLOBAL
    assert back[4].command == MavCmd.DO_CHANGE_SPEED and back[4].param2 == 0.5
    # read back differently from what was sent, accepted as what ArduCopter stores
    assert item_difference(speed, back[4]) == "frame"
