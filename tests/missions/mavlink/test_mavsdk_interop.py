"""Interoperability with a real MAVLink implementation: MAVSDK 4.x (its C++ core in-process).

(a) MAVSDK's MissionRaw, as a ground station, uploads to our mock and reads the mission back.
(b) Our upload client uploads to MAVSDK's MissionRawServer, acting as the vehicle.
"""

from __future__ import annotations

import logging
import math
import threading
from collections.abc import Iterator

import pytest
from mavsdk import ComponentType, Configuration, Mavsdk, log_subscribe, log_unsubscribe
from mavsdk.plugins.mission_raw import MissionItem as RawItem
from mavsdk.plugins.mission_raw import MissionRaw
from mavsdk.plugins.mission_raw_server import MissionRawServer, MissionRawServerResult

from missions.export.items import MavCmd, MavFrame, MissionItem
from missions.mavlink.messages import as_sent
from missions.mavlink.policy import RetryPolicy
from missions.mavlink.transport import VehicleLink
from missions.mavlink.upload import Verification, upload_and_verify
from missions.mock.autopilot import MockConfig
from tests.missions.loopback import HOME, free_udp_port, waypoint_mission

FIELDS = (
    "seq",
    "frame",
    "command",
    "autocontinue",
    "param1",
    "param2",
    "param3",
    "param4",
    "x",
    "y",
    "z",
    "mission_type",
)
logger = logging.getLogger("mavsdk")


@pytest.fixture
def mavsdk_to_logging() -> Iterator[None]:
    """MAVSDK's own log lines go to Python logging instead of stdout."""
    levels = [logging.DEBUG, logging.INFO, logging.WARNING, logging.ERROR]
    log_subscribe(
        lambda level, message, _file, _line: (logger.log(levels[int(level)], "%s", message), True)[
            1
        ]
    )
    yield
    log_unsubscribe()


def values(item) -> tuple:
    """The compared fields of either item type, NaN made comparable; ``current`` is left
    out: MAVSDK requires it on the first uploaded item, and it is vehicle state."""

    def norm(v):
        v = float(v) if not isinstance(v, int) else v
        return "nan" if isinstance(v, float) and math.isnan(v) else v

    return tuple(
        norm(
            int(getattr(item, f)) if f in ("frame", "command", "mission_type") else getattr(item, f)
        )
        for f in FIELDS
    )


def to_raw(item: MissionItem, current: int) -> RawItem:
    return RawItem(
        item.seq,
        int(item.frame),
        int(item.command),
        current,
        item.autocontinue,
        item.param1,
        item.param2,
        item.param3,
        item.param4,
        item.x,
        item.y,
        item.z,
        int(item.mission_type),
    )


def home_first(mission_items):
    """The mission with seq 0 set to what ArduPilot reads back there (its home), so that
    an unchanged read-back is an exact equality."""
    home = MissionItem(
        0,
        MavFrame.GLOBAL,
        MavCmd.NAV_WAYPOINT,
        x=round(HOME.lat_deg * 1e7),
        y=round(HOME.lon_deg * 1e7),
        z=HOME.alt_m,
    )
    return (home, *mission_items[1:])


def test_mavsdk_ground_station_uploads_to_the_mock_and_reads_it_back(spawn_mock, mavsdk_to_logging):
    mock, address = spawn_mock(MockConfig(home=HOME))
    port = int(address.rsplit(":", 1)[1])
    items = home_first(waypoint_mission(2, 12).items)
    sdk = Mavsdk(Configuration.create_with_component_type(ComponentType.GROUND_STATION))
    try:
        sdk.add_any_connection(f"udpout://127.0.0.1:{port}")
        system = sdk.first_autopilot(5.0)
        assert system is not None, "MAVSDK saw no heartbeat from the mock"
        mission_raw = MissionRaw(system)
        mission_raw.upload_mission([to_raw(i, int(i.seq == 0)) for i in items])
        stored = mock.mission
        downloaded = mission_raw.download_mission()
    finally:
        sdk.destroy()
    expected = [values(as_sent(i)) for i in items]
    assert [values(i) for i in stored] == expected
    assert [values(i) for i in downloaded] == expected


def test_our_client_uploads_to_mavsdk_mission_raw_server(mavsdk_to_logging):
    port = free_udp_port()
    policy = RetryPolicy(
        request_timeout_s=0.3, retries=3, heartbeat_timeout_s=5.0, gcs_heartbeat_interval_s=0.1
    )
    mission = waypoint_mission(3, 12)
    incoming: list = []
    arrived = threading.Event()
    requests: list[str] = []
    sdk = Mavsdk(Configuration.create_with_component_type(ComponentType.AUTOPILOT))
    try:
        with VehicleLink(f"udpin:127.0.0.1:{port}", policy, name="mavsdk") as link:
            link.add_listener(
                ("MISSION_REQUEST", "MISSION_REQUEST_INT"),
                lambda msg: requests.append(msg.get_type()),
            )
            sdk.add_any_connection(f"udpout://127.0.0.1:{port}")
            server = MissionRawServer(sdk.server_component())
            server.subscribe_incoming_mission(
                lambda result, plan, _: (
                    incoming.append((result, plan.mission_items)),
                    arrived.set(),
                )
            )
            link.wait_heartbeat()
            # MissionRawServer stores seq 0 verbatim and serves downloads: compare all
            report = upload_and_verify(link, mission, policy, Verification.ALL_ITEMS)
            assert arrived.wait(5.0)
    finally:
        sdk.destroy()
    assert report.item_count == 14
    assert set(requests) == {"MISSION_REQUEST_INT"}  # the PX4/MAVSDK way of asking
    result, items = incoming[0]
    assert result == MissionRawServerResult.SUCCESS
    assert [values(i) for i in items] == [values(as_sent(i)) for i in mission.items]
