"""MAVLink messages as plain data, and MissionItem <-> MISSION_ITEM(_INT) conversion.

Every builder returns a :data:`MessageSpec`, ``(NAME, {field: value})``, e.g.
``("MISSION_COUNT", {"target_system": 1, "target_component": 1, "count": 4,
"mission_type": 0})``. Nothing here touches a socket: :func:`to_mavlink` turns a spec into a
pymavlink message object, which a link packs and sends. So the encoding can be tested alone,
and the protocol code reads as the MAVLink documentation does.

The wire carries the params and ``z`` as float32, so a float64 value does not come back
bit-identical; :func:`as_sent` gives an item exactly as a receiver decodes it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Any

import numpy as np
from pymavlink.dialects.v20 import ardupilotmega as dialect

from missions.export.items import MavCmd, MavFrame, MissionItem, MissionType

#: ``(MESSAGE_NAME, {field: value})``: one message, not yet encoded.
MessageSpec = tuple[str, dict[str, Any]]

#: Frames whose x/y are latitude/longitude; the non-INT ones send degrees in MISSION_ITEM.
GLOBAL_FRAMES = frozenset({0, 3, 5, 6, 10, 11})

#: MISSION_ITEM_INT may use either spelling of a global frame (the INT frames are
#: deprecated and ArduPilot answers with the plain ones); both mean the same thing.
EQUIVALENT_FRAME = {5: 0, 6: 3, 11: 10}

MAV_TYPE_GCS = dialect.MAV_TYPE_GCS
MAV_AUTOPILOT_INVALID = dialect.MAV_AUTOPILOT_INVALID


@dataclass(frozen=True)
class Endpoint:
    """A MAVLink system and component (the target of a message, or its source)."""

    system: int
    component: int


def mission_result_name(code: int) -> str:
    """The MAV_MISSION_RESULT name of ``code`` (``"MAV_MISSION_NO_SPACE"`` for 4)."""
    entry = dialect.enums["MAV_MISSION_RESULT"].get(code)
    return entry.name if entry is not None else f"MAV_MISSION_RESULT_{code}"


def command_result_name(code: int) -> str:
    """The MAV_RESULT name of ``code`` (``"MAV_RESULT_DENIED"`` for 2)."""
    entry = dialect.enums["MAV_RESULT"].get(code)
    return entry.name if entry is not None else f"MAV_RESULT_{code}"


def message_id(name: str) -> int:
    """The numeric id of message ``name`` (33 for ``"GLOBAL_POSITION_INT"``)."""
    return int(getattr(dialect, f"MAVLINK_MSG_ID_{name}"))


def to_mavlink(spec: MessageSpec) -> dialect.MAVLink_message:
    """Build the pymavlink message object of ``spec`` (fields by keyword, missing ones fail)."""
    name, fields = spec
    cls = getattr(dialect, f"MAVLink_{name.lower()}_message")
    return cls(**fields)


def float32(value: float) -> float:
    """``value`` rounded to the nearest float32, as the wire carries params and z."""
    return float(np.float32(value))


def as_sent(item: MissionItem) -> MissionItem:
    """``item`` as a receiver decodes it from MISSION_ITEM_INT (float fields in float32)."""
    return replace(
        item,
        param1=float32(item.param1),
        param2=float32(item.param2),
        param3=float32(item.param3),
        param4=float32(item.param4),
        z=float32(item.z),
    )


def _target(endpoint: Endpoint) -> dict[str, int]:
    return {"target_system": endpoint.system, "target_component": endpoint.component}


def _item_fields(item: MissionItem) -> dict[str, Any]:
    return {
        "seq": item.seq,
        "frame": int(item.frame),
        "command": int(item.command),
        "current": item.current,
        "autocontinue": item.autocontinue,
        "param1": item.param1,
        "param2": item.param2,
        "param3": item.param3,
        "param4": item.param4,
        "mission_type": int(item.mission_type),
    }


def mission_item_int(item: MissionItem, target: Endpoint) -> MessageSpec:
    """MISSION_ITEM_INT carrying ``item`` (lat/lon as 1e-7 degree integers)."""
    return (
        "MISSION_ITEM_INT",
        {**_target(target), **_item_fields(item), "x": item.x, "y": item.y, "z": item.z},
    )


def mission_item_float(item: MissionItem, target: Endpoint) -> MessageSpec:
    """The deprecated MISSION_ITEM carrying ``item`` (lat/lon as float degrees).

    Only a vehicle answering a MISSION_REQUEST sends this (ArduPilot does); float32 degrees
    lose up to about 0.9 m of position (half the float32 spacing at 180 degrees), which is
    why clients request the INT form.
    """
    scale = 1e7 if int(item.frame) in GLOBAL_FRAMES else 1.0
    return (
        "MISSION_ITEM",
        {
            **_target(target),
            **_item_fields(item),
            "x": item.x / scale,
            "y": item.y / scale,
            "z": item.z,
        },
    )


def _enum_or_int(enum: type[MavFrame] | type[MavCmd] | type[MissionType], value: int) -> Any:
    try:
        return enum(value)
    except ValueError:
        return int(value)


def item_from_message(msg: Any) -> MissionItem:
    """The :class:`MissionItem` of a received MISSION_ITEM_INT or MISSION_ITEM.

    Parameters
    ----------
    msg : pymavlink message
        MISSION_ITEM_INT, or MISSION_ITEM whose global-frame x/y are float degrees (rounded
        to the nearest 1e-7 degree here).

    Raises
    ------
    ValueError
        For any other message type.
    """
    kind = msg.get_type()
    if kind == "MISSION_ITEM_INT":
        x, y = int(msg.x), int(msg.y)
    elif kind == "MISSION_ITEM":
        global_frame = msg.frame in GLOBAL_FRAMES
        x = round(msg.x * 1e7) if global_frame else round(msg.x)
        y = round(msg.y * 1e7) if global_frame else round(msg.y)
    else:
        raise ValueError(f"not a mission item: {kind}")
    return MissionItem(
        seq=int(msg.seq),
        frame=_enum_or_int(MavFrame, msg.frame),
        command=_enum_or_int(MavCmd, msg.command),
        current=int(msg.current),
        autocontinue=int(msg.autocontinue),
        param1=float(msg.param1),
        param2=float(msg.param2),
        param3=float(msg.param3),
        param4=float(msg.param4),
        x=x,
        y=y,
        z=float(msg.z),
        mission_type=_enum_or_int(MissionType, getattr(msg, "mission_type", 0)),
    )


#: The fields :func:`item_difference` compares, in the order it compares them.
COMPARED_FIELDS = ("command", "frame", "autocontinue", "mission_type", "x", "y",
                   "param1", "param2", "param3", "param4", "z")  # fmt: skip
#: Commands whose location AP_Mission stores (altitude in whole centimetres).
_STORED_LOCATION = frozenset(
    {
        MavCmd.NAV_WAYPOINT,
        MavCmd.NAV_SPLINE_WAYPOINT,
        MavCmd.NAV_LOITER_UNLIM,
        MavCmd.NAV_LAND,
        MavCmd.NAV_TAKEOFF,
    }
)


def ardupilot_frame(item: MissionItem) -> MissionItem:
    """``item`` with the frame ArduCopter reads it back in: a command without a location
    (DO_CHANGE_SPEED) sent in frame MISSION comes back in frame GLOBAL (0): AP_Mission keeps
    no frame for it (:mod:`missions.autopilots.ardupilot`)."""
    if int(item.command) in _STORED_LOCATION or item.frame != MavFrame.MISSION:
        return item
    return replace(item, frame=MavFrame.GLOBAL)


def ardupilot_readback(item: MissionItem) -> MissionItem:
    """``item`` as ArduCopter returns it on download after storing it (AP_Mission).

    A location's altitude is stored as ``z * 100.0f`` truncated to whole centimetres and
    returned as ``alt * 0.01f``; a NAV_WAYPOINT keeps only its hold time (param1, a uint16
    of whole seconds) and returns 0 for param2-4 (Copter stores no acceptance radius, pass
    radius or yaw). A command without a location comes back in frame GLOBAL
    (:func:`ardupilot_frame`). Everything else comes back as sent.
    """
    sent = as_sent(item)
    if int(item.command) not in _STORED_LOCATION:
        return ardupilot_frame(sent)
    centimetres = np.trunc(np.float32(item.z) * np.float32(100.0))
    stored = replace(sent, z=float(np.float32(centimetres) * np.float32(0.01)))
    if int(item.command) == MavCmd.NAV_WAYPOINT:
        hold = float(math.trunc(item.param1)) if 0 <= item.param1 < 65536 else item.param1
        stored = replace(stored, param1=hold, param2=0.0, param3=0.0, param4=0.0)
    return stored


def item_difference(expected: MissionItem, actual: MissionItem) -> str | None:
    """The first field in which ``actual`` differs from ``expected`` as sent, or None.

    Compared as the wire carries them: params and z in float32 (NaN equals NaN, since
    MAVLink uses NaN for "unset"), x/y exactly, the INT and plain spelling of a global frame
    as equal. ``current`` is vehicle state (which item is active), not mission content, and
    is not compared.
    """
    sent = as_sent(expected)
    for name in COMPARED_FIELDS[:6]:
        want, got = int(getattr(sent, name)), int(getattr(actual, name))
        if name == "frame":
            want, got = EQUIVALENT_FRAME.get(want, want), EQUIVALENT_FRAME.get(got, got)
        if want != got:
            return name
    for name in COMPARED_FIELDS[6:]:
        value, back = getattr(sent, name), float32(getattr(actual, name))
        if not (value == back or (math.isnan(value) and math.isnan(back))):
            return name
    return None


def mission_count(count: int, target: Endpoint, mission_type: int = 0) -> MessageSpec:
    return ("MISSION_COUNT", {**_target(target), "count": count, "mission_type": mission_type})


def mission_request_list(target: Endpoint, mission_type: int = 0) -> MessageSpec:
    return ("MISSION_REQUEST_LIST", {**_target(target), "mission_type": mission_type})


def mission_request_int(seq: int, target: Endpoint, mission_type: int = 0) -> MessageSpec:
    return ("MISSION_REQUEST_INT", {**_target(target), "seq": seq, "mission_type": mission_type})


def mission_request(seq: int, target: Endpoint, mission_type: int = 0) -> MessageSpec:
    """The deprecated MISSION_REQUEST, which ArduCopter still uses to ask for upload items."""
    return ("MISSION_REQUEST", {**_target(target), "seq": seq, "mission_type": mission_type})


def mission_ack(result: int, target: Endpoint, mission_type: int = 0) -> MessageSpec:
    return ("MISSION_ACK", {**_target(target), "type": result, "mission_type": mission_type})


def mission_clear_all(target: Endpoint, mission_type: int = 0) -> MessageSpec:
    return ("MISSION_CLEAR_ALL", {**_target(target), "mission_type": mission_type})


def mission_set_current(seq: int, target: Endpoint) -> MessageSpec:
    return ("MISSION_SET_CURRENT", {**_target(target), "seq": seq})


def mission_current(seq: int, total: int) -> MessageSpec:
    return ("MISSION_CURRENT", {"seq": seq, "total": total, "mission_state": 0, "mission_mode": 0})


def mission_item_reached(seq: int) -> MessageSpec:
    return ("MISSION_ITEM_REACHED", {"seq": seq})


def heartbeat(
    mav_type: int, autopilot: int, base_mode: int = 0, custom_mode: int = 0, status: int = 0
) -> MessageSpec:
    """HEARTBEAT; a ground station sends ``MAV_TYPE_GCS`` with ``MAV_AUTOPILOT_INVALID``."""
    return (
        "HEARTBEAT",
        {
            "type": mav_type,
            "autopilot": autopilot,
            "base_mode": base_mode,
            "custom_mode": custom_mode,
            "system_status": status,
            "mavlink_version": 3,
        },
    )


def command_long(
    command: int, target: Endpoint, params: tuple[float, ...] = (), confirmation: int = 0
) -> MessageSpec:
    """COMMAND_LONG with up to seven params (missing ones are 0)."""
    if len(params) > 7:
        raise ValueError(f"COMMAND_LONG has 7 params, got {len(params)}")
    padded = tuple(params) + (0.0,) * (7 - len(params))
    fields = {f"param{i + 1}": float(v) for i, v in enumerate(padded)}
    return (
        "COMMAND_LONG",
        {**_target(target), "command": command, "confirmation": confirmation, **fields},
    )


def command_ack(command: int, result: int, target: Endpoint) -> MessageSpec:
    return (
        "COMMAND_ACK",
        {
            "command": command,
            "result": result,
            "progress": 0,
            "result_param2": 0,
            **_target(target),
        },
    )


def message_interval_params(name: str, interval_s: float) -> tuple[float, float]:
    """Params of MAV_CMD_SET_MESSAGE_INTERVAL asking for ``name`` every ``interval_s`` [s]
    (param2 is in microseconds)."""
    return (float(message_id(name)), interval_s * 1e6)


def request_data_stream(
    stream: int, rate_hz: int, target: Endpoint, start: bool = True
) -> MessageSpec:
    """The older REQUEST_DATA_STREAM (ArduPilot's SRx_ rates) for MAV_DATA_STREAM ``stream``."""
    return (
        "REQUEST_DATA_STREAM",
        {
            **_target(target),
            "req_stream_id": stream,
            "req_message_rate": rate_hz,
            "start_stop": int(start),
        },
    )


def global_position_int(
    time_boot_ms: int,
    lat_e7: int,
    lon_e7: int,
    alt_mm: int,
    relative_alt_mm: int,
    velocity_ned_cms: tuple[int, int, int],
    heading_cdeg: int,
) -> MessageSpec:
    vx, vy, vz = velocity_ned_cms
    return (
        "GLOBAL_POSITION_INT",
        {
            "time_boot_ms": time_boot_ms,
            "lat": lat_e7,
            "lon": lon_e7,
            "alt": alt_mm,
            "relative_alt": relative_alt_mm,
            "vx": vx,
            "vy": vy,
            "vz": vz,
            "hdg": heading_cdeg,
        },
    )


def param_set(name: str, value: float, target: Endpoint) -> MessageSpec:
    """PARAM_SET of ``name`` (at most 16 characters) to ``value`` as a float32 (ArduPilot
    stores every parameter type and converts; it answers with PARAM_VALUE)."""
    return (
        "PARAM_SET",
        {
            **_target(target),
            "param_id": name.encode("ascii"),
            "param_value": float(value),
            "param_type": dialect.MAV_PARAM_TYPE_REAL32,
        },
    )


def param_request_read(name: str, target: Endpoint) -> MessageSpec:
    """PARAM_REQUEST_READ of ``name`` by name (param_index -1)."""
    return (
        "PARAM_REQUEST_READ",
        {**_target(target), "param_id": name.encode("ascii"), "param_index": -1},
    )


def param_value(name: str, value: float, param_type: int, count: int, index: int) -> MessageSpec:
    """PARAM_VALUE: what a vehicle answers to PARAM_SET and PARAM_REQUEST_READ."""
    return (
        "PARAM_VALUE",
        {
            "param_id": name.encode("ascii"),
            "param_value": float(value),
            "param_type": param_type,
            "param_count": count,
            "param_index": index,
        },
    )
