"""MissionItem <-> MISSION_ITEM_INT, checked against the wire layout of the MAVLink spec."""

from __future__ import annotations

import math
import struct

from hypothesis import given
from hypothesis import strategies as st

from missions.export.items import MavCmd, MavFrame, MissionItem, MissionType
from missions.mavlink.messages import (
    Endpoint,
    as_sent,
    dialect,
    float32,
    item_difference,
    item_from_message,
    mission_item_float,
    mission_item_int,
    mission_result_name,
    to_mavlink,
)

TARGET = Endpoint(7, 1)
floats = st.floats(allow_nan=True, allow_infinity=False, width=32)
items = st.builds(
    MissionItem,
    seq=st.integers(0, 65535),
    frame=st.sampled_from(list(MavFrame)),
    command=st.sampled_from(list(MavCmd)),
    current=st.integers(0, 1),
    autocontinue=st.integers(0, 1),
    param1=floats,
    param2=floats,
    param3=floats,
    param4=floats,
    x=st.integers(-900_000_000, 900_000_000),
    y=st.integers(-1_800_000_000, 1_800_000_000),
    z=st.floats(-1000, 10000),
    mission_type=st.sampled_from(list(MissionType)),
)


def wire_bytes(spec) -> bytes:
    """The complete MAVLink 2 frame of ``spec``, as a socket would carry it."""
    return to_mavlink(spec).pack(dialect.MAVLink(None, srcSystem=255, srcComponent=190))


def same(a: float, b: float) -> bool:
    return a == b or (math.isnan(a) and math.isnan(b))


@given(items)
def test_item_survives_the_wire(item):
    frame = wire_bytes(mission_item_int(item, TARGET))
    decoded = dialect.MAVLink(None).decode(bytearray(frame))
    back = item_from_message(decoded)
    assert item_difference(item, back) is None
    assert (back.seq, back.x, back.y, back.current) == (item.seq, item.x, item.y, item.current)
    assert int(back.frame) == int(item.frame) and int(back.command) == int(item.command)


@given(items)
def test_payload_layout_matches_the_mavlink_definition(item):
    """MISSION_ITEM_INT (id 73) payload, fields ordered by size as MAVLink 2 sends them:
    param1-4, x, y (int32), z, seq, command, target sys/comp, frame, current, autocontinue,
    mission_type; trailing zero bytes are truncated on the wire."""
    frame = wire_bytes(mission_item_int(item, TARGET))
    assert frame[0] == 0xFD  # MAVLink 2
    length, msgid = frame[1], int.from_bytes(frame[7:10], "little")
    assert msgid == 73
    payload = frame[10 : 10 + length].ljust(38, b"\0")
    p1, p2, p3, p4, x, y, z, seq, cmd, ts, tc, fr, cur, auto, mtype = struct.unpack(
        "<ffffiifHHBBBBBB", payload
    )
    assert (x, y, seq, cmd, ts, tc) == (item.x, item.y, item.seq, int(item.command), 7, 1)
    assert (fr, cur, auto, mtype) == (
        int(item.frame),
        item.current,
        item.autocontinue,
        int(item.mission_type),
    )
    for sent, raw in zip(
        (item.param1, item.param2, item.param3, item.param4, item.z),
        (p1, p2, p3, p4, z),
        strict=True,
    ):
        assert same(float32(sent), raw)


def test_float_params_are_compared_as_float32():
    item = MissionItem(
        3, MavFrame.GLOBAL_RELATIVE_ALT_INT, MavCmd.NAV_WAYPOINT, param1=0.1, z=12.3456789
    )
    assert as_sent(item).param1 != 0.1  # 0.1 has no exact float32
    assert item_difference(item, as_sent(item)) is None
    assert item_difference(item, as_sent(item).with_seq(3)) is None
    nudged = MissionItem(
        3, MavFrame.GLOBAL_RELATIVE_ALT_INT, MavCmd.NAV_WAYPOINT, param1=0.1, z=12.35
    )
    assert item_difference(item, nudged) == "z"


def test_global_frames_compare_equal_in_either_spelling_current_is_state():
    sent = MissionItem(1, MavFrame.GLOBAL_RELATIVE_ALT_INT, MavCmd.NAV_WAYPOINT, x=1, y=2)
    as_ardupilot_returns = MissionItem(
        1, MavFrame.GLOBAL_RELATIVE_ALT, MavCmd.NAV_WAYPOINT, current=1, x=1, y=2
    )
    assert item_difference(sent, as_ardupilot_returns) is None
    amsl = MissionItem(1, MavFrame.GLOBAL, MavCmd.NAV_WAYPOINT, x=1, y=2)
    assert item_difference(sent, amsl) == "frame"
    assert item_difference(sent, MissionItem(1, sent.frame, MavCmd.NAV_LAND, x=1, y=2)) == (
        "command"
    )
    assert item_difference(sent, MissionItem(1, sent.frame, sent.command, x=1, y=3)) == "y"


def test_float_mission_item_carries_degrees():
    """The legacy MISSION_ITEM sends degrees as float32, so it loses some position."""
    item = MissionItem(
        2, MavFrame.GLOBAL_RELATIVE_ALT, MavCmd.NAV_WAYPOINT, x=473977421, y=85455941, z=10.0
    )
    name, fields = mission_item_float(item, TARGET)
    assert name == "MISSION_ITEM" and fields["x"] == 47.3977421
    decoded = dialect.MAVLink(None).decode(bytearray(wire_bytes((name, fields))))
    back = item_from_message(decoded)
    # float32 spacing at 47 degrees is 2**-18 degree = 38 units of 1e-7 degree
    assert abs(back.x - item.x) <= 20 and abs(back.y - item.y) <= 5
    mission_frame = MissionItem(3, MavFrame.MISSION, MavCmd.DO_CHANGE_SPEED, param2=2.0)
    assert mission_item_float(mission_frame, TARGET)[1]["x"] == 0


def test_unknown_frames_and_commands_stay_numbers():
    fields = mission_item_int(MissionItem(1, 10, 31000, x=1, y=2), TARGET)
    decoded = dialect.MAVLink(None).decode(bytearray(wire_bytes(fields)))
    back = item_from_message(decoded)
    assert (back.frame, back.command) == (10, 31000)
    assert mission_result_name(4) == "MAV_MISSION_NO_SPACE"
    assert mission_result_name(99) == "MAV_MISSION_RESULT_99"
