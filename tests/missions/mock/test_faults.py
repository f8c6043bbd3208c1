"""Lossy links, silent vehicles and refusals: complete missions or typed errors, never a
half-uploaded mission reported as success."""

from __future__ import annotations

import threading
import time
from dataclasses import replace

import pytest

from missions.mavlink.errors import (
    FinalAckTimeoutError,
    MavlinkTimeoutError,
    MissionTransferError,
)
from missions.mavlink.messages import (
    as_sent,
    dialect,
    mission_count,
    mission_item_int,
    mission_request_list,
)
from missions.mavlink.policy import RetryPolicy
from missions.mavlink.transport import VehicleLink
from missions.mavlink.upload import Verification, upload_and_verify
from missions.mock.autopilot import MockConfig
from missions.mock.faults import FaultInjection
from missions.mock.sim_clock import SimClock
from tests.missions.loopback import HOME, waypoint_mission
from tests.missions.mavlink.test_upload import comparable

# Loopback round trips take milliseconds; many retries make a 20 % loss harmless (five
# silences in a row at 36 % loss per round trip: about 1 %; eleven: 1e-5).
LOSSY_POLICY = RetryPolicy(
    request_timeout_s=0.1,
    retries=10,
    deadline_s=30.0,
    heartbeat_timeout_s=3.0,
    gcs_heartbeat_interval_s=0.1,
)


@pytest.mark.parametrize(
    "faults",
    [
        FaultInjection(drop_incoming=0.2, drop_outgoing=0.2, seed=1),
        FaultInjection(duplicate_incoming=0.2, duplicate_outgoing=0.2, seed=2),
        FaultInjection(
            drop_incoming=0.2,
            drop_outgoing=0.2,
            duplicate_incoming=0.2,
            duplicate_outgoing=0.2,
            seed=3,
        ),
    ],
    ids=["drop", "duplicate", "both"],
)
def test_lossy_link_still_delivers_the_complete_mission(spawn_mock, faults):
    mock, address = spawn_mock(MockConfig(home=HOME, faults=faults), SimClock(10.0))
    mission = waypoint_mission(1, 20)
    resends = []
    with VehicleLink(address, LOSSY_POLICY) as link:
        link.wait_heartbeat()
        link.add_listener(("MISSION_ACK",), lambda msg: resends.append(msg.type))
        report = upload_and_verify(link, mission, LOSSY_POLICY)
    assert report.item_count == 22
    assert comparable(mock.mission[1:]) == comparable(as_sent(i) for i in mission.items[1:])
    if faults.duplicate_incoming:
        # duplicated items made the vehicle answer INVALID_SEQUENCE, which is not final
        assert dialect.MAV_MISSION_INVALID_SEQUENCE in resends


def test_vehicle_that_never_answers_gives_the_timeout_error_in_time(spawn_mock):
    _, address = spawn_mock(MockConfig(home=HOME, faults=FaultInjection(unresponsive=True)))
    policy = RetryPolicy(
        request_timeout_s=0.2, retries=2, heartbeat_timeout_s=3.0, gcs_heartbeat_interval_s=0.1
    )
    with VehicleLink(address, policy, name="mute") as link:
        link.wait_heartbeat()  # its heartbeats do arrive
        started = time.monotonic()
        with pytest.raises(MavlinkTimeoutError) as error:
            upload_and_verify(link, waypoint_mission(1, 3), policy)
        elapsed = time.monotonic() - started
    assert error.value.vehicle == "mute"
    assert error.value.stage == "upload: MISSION_REQUEST for item 0"
    assert error.value.timeout_s == pytest.approx(0.6)  # 0.2 s x (2 resends + 1)
    # the stated wait, plus the attempt to clear (two 0.2 s requests), plus scheduling slack
    assert 0.6 <= elapsed < 0.6 + 0.4 + 0.3


@pytest.mark.parametrize(
    ("bad", "code", "name"),
    [
        ({"frame": 1}, 2, "MAV_MISSION_UNSUPPORTED_FRAME"),  # MAV_FRAME_LOCAL_NED
        ({"command": 31000}, 3, "MAV_MISSION_UNSUPPORTED"),  # a user-defined command
        ({"x": 910_000_000}, 10, "MAV_MISSION_INVALID_PARAM5_X"),  # latitude 91 degrees
        ({"y": -1_810_000_000}, 11, "MAV_MISSION_INVALID_PARAM6_Y"),  # longitude -181
    ],
)
def test_refused_item_gives_the_typed_error_and_leaves_no_half_mission(
    spawn_mock, fast_policy, bad, code, name
):
    mock, address = spawn_mock()
    good = waypoint_mission(1, 6)
    with VehicleLink(address, fast_policy, name="v1") as link:
        link.wait_heartbeat()
        upload_and_verify(link, good, fast_policy)  # a complete mission on board
        items = list(good.items)
        items[4] = replace(items[4], **bad)
        with pytest.raises(MissionTransferError) as error:
            upload_and_verify(link, items, fast_policy)
    assert (error.value.vehicle, error.value.operation) == ("v1", "upload")
    assert (error.value.result, error.value.result_name, error.value.seq) == (code, name, 4)
    # neither the half-written new mission nor the old one is left to be flown
    assert len(mock.mission) == 1


def test_vehicle_vanishing_mid_upload_is_a_timeout_not_a_success(spawn_mock, fast_policy):
    mock, address = spawn_mock()
    vanished = threading.Event()

    def pull_the_plug(msg):
        # stopped on the link's reader thread, before it reads anything more: a thread of
        # its own let a loaded host answer the whole upload before the vehicle was gone
        if msg.seq == 5 and not vanished.is_set():
            vanished.set()
            mock.stop()

    with VehicleLink(address, fast_policy) as link:
        link.wait_heartbeat()
        link.add_listener(("MISSION_REQUEST",), pull_the_plug)
        with pytest.raises(MavlinkTimeoutError) as error:
            upload_and_verify(link, waypoint_mission(1, 10), fast_policy)
    # it vanished as item 5 was requested: item 5 may have reached it, item 7 cannot
    stage, _, item = error.value.stage.rpartition(" ")
    assert stage == "upload: MISSION_REQUEST for item" and int(item) in (6, 7)
    assert len(mock.mission) < 12  # half a mission on board, and no success reported


def raw_exchange(link, spec, kinds, timeout=1.0):
    with link.subscribe(kinds) as inbox:
        link.send(spec)
        return inbox.get(timeout)


def test_mock_refuses_items_out_of_order_but_keeps_the_transfer_open(spawn_mock, fast_policy):
    _, address = spawn_mock(clock=SimClock(20.0))
    items = waypoint_mission(1, 1).items  # three items
    kinds = ("MISSION_REQUEST", "MISSION_ACK")
    with VehicleLink(address, fast_policy) as link:
        link.wait_heartbeat()
        first = raw_exchange(link, mission_count(3, link.target), kinds)
        assert (first.get_type(), first.seq) == ("MISSION_REQUEST", 0)
        wrong = raw_exchange(link, mission_item_int(items[2], link.target), kinds)
        assert (wrong.get_type(), wrong.type) == ("MISSION_ACK", 13)  # INVALID_SEQUENCE
        busy = raw_exchange(link, mission_request_list(link.target), ("MISSION_ACK",))
        assert busy.type == 14  # DENIED: no download while an upload is open
        right = raw_exchange(link, mission_item_int(items[0], link.target), kinds)
        assert (right.get_type(), right.seq) == ("MISSION_REQUEST", 1)
        # then silence: it re-asks every simulated second and cancels after eight
        # (8 s simulated = 0.4 s at speed-up 20)
        seen = []
        with link.subscribe(kinds) as inbox:
            while (msg := inbox.get(1.0)) is not None:
                seen.append(
                    (msg.get_type(), msg.seq if msg.get_type() != "MISSION_ACK" else msg.type)
                )
                if msg.get_type() == "MISSION_ACK":
                    break
    assert seen.count(("MISSION_REQUEST", 1)) >= 5
    assert seen[-1] == ("MISSION_ACK", 15)  # OPERATION_CANCELLED


class AckEatingLink(VehicleLink):
    """A ground link that loses the first MISSION_ACK ACCEPTED it receives."""

    eaten = 0

    def _dispatch(self, msg):
        if msg.get_type() == "MISSION_ACK" and msg.type == 0 and not self.eaten:
            self.eaten += 1
            return
        super()._dispatch(msg)


@pytest.mark.parametrize("verification", [Verification.ARDUPILOT, Verification.NONE])
def test_lost_final_ack_is_settled_by_the_read_back_only(spawn_mock, fast_policy, verification):
    mock, address = spawn_mock()
    mission = waypoint_mission(1, 4)
    with AckEatingLink(address, fast_policy) as link:
        link.wait_heartbeat()
        if verification is Verification.NONE:
            with pytest.raises(FinalAckTimeoutError) as error:
                upload_and_verify(link, mission, fast_policy, verification)
            assert error.value.stage == "upload: MISSION_ACK"
            assert len(mock.mission) == 1  # unproven, so cleared
        else:
            report = upload_and_verify(link, mission, fast_policy, verification)
            assert report.item_count == 6 and len(mock.mission) == 6
        assert link.eaten == 1
