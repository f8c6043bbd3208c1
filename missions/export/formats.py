"""File encodings of missions: ``QGC WPL 110`` (.waypoints), QGroundControl ``.plan``, JSON.

Files carry latitude and longitude as decimal degrees, so the wire frames with integer
coordinates map to their float twins (GLOBAL_INT -> GLOBAL, GLOBAL_RELATIVE_ALT_INT ->
GLOBAL_RELATIVE_ALT), as Mission Planner and QGroundControl write them. Coordinates are
printed with 8 decimals: they are exact multiples of 1e-7 degree already.

- ``.waypoints``: Mission Planner / MAVProxy / pymavlink ``mavwp`` text format, line 0 is
  the home (seq 0), tab-separated ``seq current frame command p1 p2 p3 p4 lat lon alt
  autocontinue``.
- ``.plan``: QGroundControl's JSON (fileType "Plan", mission version 2); home goes to
  ``plannedHomePosition`` and the items start at seq 1, as QGC does.
- ``mission.json``: our own lossless form of the MISSION_ITEM_INT fields, for tools and for
  uploading a stored mission again (:func:`mission_from_json`).
"""

from __future__ import annotations

import json
import math
from typing import Any

from missions.export.items import DroneMission, MavFrame, MissionItem
from missions.geodesy import DEGREE_UNIT

#: Wire frame -> file frame (decimal degrees).
FILE_FRAME: dict[int, MavFrame] = {
    MavFrame.GLOBAL_INT: MavFrame.GLOBAL,
    MavFrame.GLOBAL_RELATIVE_ALT_INT: MavFrame.GLOBAL_RELATIVE_ALT,
}
#: MAV_AUTOPILOT_ARDUPILOTMEGA and MAV_TYPE_QUADROTOR, for QGC's plan header.
FIRMWARE_ARDUPILOT, VEHICLE_QUADROTOR = 3, 2


def _file_frame(item: MissionItem) -> int:
    frame = int(item.frame)
    return int(FILE_FRAME.get(frame, frame))


def _degrees(value: int) -> float:
    return value * DEGREE_UNIT


def waypoints_text(mission: DroneMission) -> str:
    """The mission as a ``QGC WPL 110`` file."""
    lines = ["QGC WPL 110"]
    for item in mission.items:
        fields = [
            str(item.seq),
            "1" if item.seq == 0 else "0",
            str(_file_frame(item)),
            str(int(item.command)),
            *(f"{p:.8f}" for p in (item.param1, item.param2, item.param3, item.param4)),
            f"{_degrees(item.x):.8f}",
            f"{_degrees(item.y):.8f}",
            f"{item.z:.6f}",
            str(item.autocontinue),
        ]
        lines.append("\t".join(fields))
    return "\n".join(lines) + "\n"


def qgc_plan(mission: DroneMission, cruise_speed: float) -> dict[str, Any]:
    """The mission as a QGroundControl ``.plan`` document."""
    home, *rest = mission.items
    items = []
    for item in rest:
        params = [
            item.param1,
            item.param2,
            item.param3,
            item.param4,
            _degrees(item.x),
            _degrees(item.y),
            item.z,
        ]
        entry: dict[str, Any] = {
            "autoContinue": bool(item.autocontinue),
            "command": int(item.command),
            "doJumpId": item.seq,
            "frame": _file_frame(item),
            "params": [round(p, 8) for p in params],
            "type": "SimpleItem",
        }
        if item.frame != MavFrame.MISSION:
            entry["Altitude"] = item.z
            entry["AltitudeMode"] = 1 if entry["frame"] == MavFrame.GLOBAL_RELATIVE_ALT else 2
            entry["AMSLAltAboveTerrain"] = None
        items.append(entry)
    return {
        "fileType": "Plan",
        "version": 1,
        "groundStation": "FlyCrane",
        "geoFence": {"circles": [], "polygons": [], "version": 2},
        "rallyPoints": {"points": [], "version": 2},
        "mission": {
            "version": 2,
            "firmwareType": FIRMWARE_ARDUPILOT,
            "vehicleType": VEHICLE_QUADROTOR,
            "cruiseSpeed": cruise_speed,
            "hoverSpeed": cruise_speed,
            "plannedHomePosition": [round(_degrees(home.x), 8), round(_degrees(home.y), 8), home.z],
            "items": items,
        },
    }


def mission_json(mission: DroneMission) -> dict[str, Any]:
    """Lossless JSON of a mission (every MISSION_ITEM_INT field)."""
    fields = list(MissionItem.__dataclass_fields__)
    return {
        "drone": mission.drone,
        "items": [
            {
                f: int(v) if f in ("frame", "command", "mission_type") else v
                for f, v in ((f, getattr(i, f)) for f in fields)
            }
            for i in mission.items
        ],
    }


def mission_from_json(data: dict[str, Any]) -> DroneMission:
    """Inverse of :func:`mission_json`; ValueError where the items are not a mission's
    (none, or their seq not 0, 1, 2, ... in order)."""
    items = tuple(MissionItem(**item) for item in data["items"])
    if not items or [item.seq for item in items] != list(range(len(items))):
        raise ValueError("items: a mission's items have seq 0, 1, 2, ... in order")
    return DroneMission(drone=int(data["drone"]), items=items)


def dumps(document: dict[str, Any]) -> str:
    return json.dumps(document, indent=2) + "\n"


def finite(document: Any) -> Any:
    """``document`` with every float that is not finite as None: JSON has no infinity and
    no NaN (RFC 8259), and strict readers (JavaScript's ``JSON.parse``) refuse them."""
    if isinstance(document, float):
        return document if math.isfinite(document) else None
    if isinstance(document, dict):
        return {key: finite(value) for key, value in document.items()}
    if isinstance(document, list | tuple):
        return [finite(value) for value in document]
    return document


def mission_files(mission: DroneMission, max_speed: float) -> dict[str, str]:
    """The texts of a mission's three files, by suffix: ``waypoints``, ``plan`` (with
    QGroundControl's cruise speed ``max_speed`` [m/s]) and ``mission.json``."""
    return {
        "waypoints": waypoints_text(mission),
        "plan": dumps(qgc_plan(mission, max_speed)),
        "mission.json": dumps(mission_json(mission)),
    }
