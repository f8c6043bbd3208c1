"""MAVLink mission items as plain data, kept apart from any encoding or transport.

A :class:`MissionItem` carries exactly the fields of MISSION_ITEM_INT (MAVLink common
message 73), so the same object feeds the wire protocol, the ``.waypoints`` and ``.plan``
files and the logs. Coordinates are integers of 1e-7 degree (``x`` latitude, ``y``
longitude), as the protocol sends them; ``z`` is metres in the item's frame.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from enum import IntEnum


class MavFrame(IntEnum):
    """The MAV_FRAME values missions use."""

    GLOBAL = 0  #: altitude AMSL, coordinates as float degrees (files)
    MISSION = 2  #: no coordinates: DO_ commands
    GLOBAL_RELATIVE_ALT = 3  #: altitude above home, float degrees (files)
    GLOBAL_INT = 5  #: altitude AMSL, coordinates as 1e-7 degree integers (wire)
    GLOBAL_RELATIVE_ALT_INT = 6  #: altitude above home, 1e-7 degree integers (wire)


class MavCmd(IntEnum):
    """The MAV_CMD values missions use."""

    NAV_WAYPOINT = 16
    NAV_LOITER_UNLIM = 17
    NAV_LAND = 21
    NAV_TAKEOFF = 22
    NAV_SPLINE_WAYPOINT = 82
    NAV_DELAY = 93
    DO_CHANGE_SPEED = 178
    MISSION_START = 300
    NAV_SCRIPT_TIME = 42702


class MissionType(IntEnum):
    """MAV_MISSION_TYPE."""

    MISSION = 0
    FENCE = 1
    RALLY = 2


@dataclass(frozen=True)
class MissionItem:
    """One MISSION_ITEM_INT, field for field (params as in the MAV_CMD's definition)."""

    seq: int
    frame: MavFrame | int  #: an int for frames outside MavFrame (e.g. read from a vehicle)
    command: MavCmd | int
    current: int = 0
    autocontinue: int = 1
    param1: float = 0.0
    param2: float = 0.0
    param3: float = 0.0
    param4: float = 0.0
    x: int = 0  #: latitude [1e-7 deg] (or a local x for non-global frames)
    y: int = 0  #: longitude [1e-7 deg]
    z: float = 0.0  #: altitude [m] in ``frame``
    mission_type: MissionType = MissionType.MISSION

    def with_seq(self, seq: int) -> MissionItem:
        return replace(self, seq=seq)


@dataclass(frozen=True)
class DroneMission:
    """The mission of one drone (1-based ``drone``), items in sequence order from seq 0."""

    drone: int
    items: tuple[MissionItem, ...] = field(default_factory=tuple)

    def __post_init__(self) -> None:
        for expected, item in enumerate(self.items):
            if item.seq != expected:
                raise ValueError(
                    f"drone {self.drone}: item at position {expected} has seq {item.seq}"
                )
