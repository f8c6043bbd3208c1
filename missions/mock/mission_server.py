"""The vehicle side of the MAVLink mission protocol, as ArduCopter 4.5 runs it.

Pure logic: :meth:`MissionServer.handle` takes a received message and returns the messages
to send back, :meth:`MissionServer.tick` the ones due because time passed. The mock
autopilot puts a socket around it. It answers as ArduCopter does
(:mod:`missions.autopilots.ardupilot`, "Mission protocol"; design.md section 9), and:

- Upload: MISSION_COUNT truncates the stored mission to ``count``; ``request_int`` asks
  for the items with MISSION_REQUEST_INT instead, as PX4 and MAVSDK do; MISSION_ITEM_INT
  and MISSION_ITEM are accepted. A stalled upload is cancelled with
  MAV_MISSION_OPERATION_CANCELLED. An item the vehicle cannot fly ends the transfer with
  MAV_MISSION_UNSUPPORTED (command), _UNSUPPORTED_FRAME, _INVALID_PARAM5_X (latitude) or
  _INVALID_PARAM6_Y (longitude).
- Download: MISSION_REQUEST_INT gets MISSION_ITEM_INT, MISSION_REQUEST gets MISSION_ITEM,
  each item as ArduCopter reads it back (:func:`~missions.mavlink.messages.ardupilot_frame`;
  seq 0 the current home, frame GLOBAL, altitude AMSL). A request during an upload is
  DENIED.
- Only the MISSION type is kept; fence and rally transfers are MAV_MISSION_UNSUPPORTED.
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from missions.export.items import MavCmd, MavFrame, MissionItem
from missions.mavlink.messages import (
    Endpoint,
    MessageSpec,
    ardupilot_frame,
    dialect,
    item_from_message,
    mission_ack,
    mission_count,
    mission_item_float,
    mission_item_int,
    mission_request,
    mission_request_int,
    mission_result_name,
)
from missions.mock.kinematic_flight import LOCATION_COMMANDS, SUPPORTED_COMMANDS

logger = logging.getLogger(__name__)

#: ArduPilot re-sends the MISSION_REQUEST after this silence [s] (wp_recv_timeout_ms)...
REREQUEST_AFTER_S = 1.0
#: ... and cancels the upload after this one (upload_timeout_ms) [s].
UPLOAD_TIMEOUT_S = 8.0

ACCEPTED = dialect.MAV_MISSION_ACCEPTED
FLYABLE_FRAMES = frozenset({0, 3, 5, 6})  # GLOBAL, GLOBAL_RELATIVE_ALT and their _INT forms
ITEM_FRAMES = FLYABLE_FRAMES | {2}  # plus MISSION, for do-commands


def item_problem(item: MissionItem) -> int:
    """The MAV_MISSION_RESULT the vehicle gives ``item`` (ACCEPTED if it can fly it)."""
    if int(item.command) not in SUPPORTED_COMMANDS:
        return dialect.MAV_MISSION_UNSUPPORTED
    frames = FLYABLE_FRAMES if int(item.command) in LOCATION_COMMANDS else ITEM_FRAMES
    if int(item.frame) not in frames:
        return dialect.MAV_MISSION_UNSUPPORTED_FRAME
    if int(item.command) in LOCATION_COMMANDS:
        if not -900_000_000 <= item.x <= 900_000_000:
            return dialect.MAV_MISSION_INVALID_PARAM5_X
        if not -1_800_000_000 <= item.y <= 1_800_000_000:
            return dialect.MAV_MISSION_INVALID_PARAM6_Y
    return ACCEPTED


@dataclass
class _Upload:
    """An upload in progress: who sends it, how many items, which one is awaited."""

    sender: Endpoint
    count: int
    expected: int
    last_item_time: float
    last_request_time: float


class MissionServer:
    """Stored mission and transfer state of one mock vehicle (module docstring).

    Parameters
    ----------
    own : Endpoint
        The vehicle's system and component (source of what it sends).
    home : Callable[[], MissionItem]
        Gives the current home as seq 0 reads back.
    max_items : int
        A larger MISSION_COUNT is refused with MAV_MISSION_NO_SPACE (as ArduPilot does).
    request_int : bool
        Ask for upload items with MISSION_REQUEST_INT instead of ArduPilot's MISSION_REQUEST.
    """

    def __init__(
        self,
        own: Endpoint,
        home: Callable[[], MissionItem],
        max_items: int,
        request_int: bool = False,
    ) -> None:
        self.own = own
        self._home = home
        self.max_items = max_items
        self._request = mission_request_int if request_int else mission_request
        self._items: list[MissionItem] = [home()]
        self._upload: _Upload | None = None

    @property
    def items(self) -> tuple[MissionItem, ...]:
        """The stored mission as a download returns it (seq 0 = current home)."""
        return (self._home(), *self._items[1:])

    def clear(self) -> None:
        """Forget everything but home (MISSION_CLEAR_ALL)."""
        self._items = [self._home()]
        self._upload = None

    def handle(self, msg: Any, now: float, booting: bool) -> list[MessageSpec]:
        """Answer one received mission-protocol message at simulated time ``now`` [s]."""
        sender = Endpoint(msg.get_srcSystem(), msg.get_srcComponent())
        kind = msg.get_type()
        mission_type = getattr(msg, "mission_type", 0)
        if kind in ("MISSION_COUNT", "MISSION_REQUEST_LIST", "MISSION_CLEAR_ALL") and (
            mission_type not in (0, dialect.MAV_MISSION_TYPE_ALL)
        ):
            return [mission_ack(dialect.MAV_MISSION_UNSUPPORTED, sender, mission_type)]
        if kind == "MISSION_COUNT":
            return self._on_count(msg.count, sender, now, booting)
        if kind in ("MISSION_ITEM_INT", "MISSION_ITEM"):
            return self._on_item(item_from_message(msg), sender, now)
        if kind == "MISSION_REQUEST_LIST":
            if self._upload is not None:
                return [mission_ack(dialect.MAV_MISSION_DENIED, sender)]
            return [mission_count(len(self._items), sender)]
        if kind in ("MISSION_REQUEST_INT", "MISSION_REQUEST"):
            return self._on_request(msg.seq, sender, as_int=kind == "MISSION_REQUEST_INT")
        if kind == "MISSION_CLEAR_ALL":
            if self._upload is not None and self._upload.sender != sender:
                return [mission_ack(dialect.MAV_MISSION_DENIED, sender)]
            self.clear()
            return [mission_ack(ACCEPTED, sender)]
        return []  # MISSION_ACK closing a download needs no answer

    def tick(self, now: float) -> list[MessageSpec]:
        """Re-request or cancel a stalled upload (ArduPilot's timers)."""
        upload = self._upload
        if upload is None:
            return []
        if now - upload.last_item_time > UPLOAD_TIMEOUT_S:
            self._upload = None
            logger.info("upload from %s timed out at item %d", upload.sender, upload.expected)
            return [mission_ack(dialect.MAV_MISSION_OPERATION_CANCELLED, upload.sender)]
        if now - upload.last_request_time > REREQUEST_AFTER_S:
            upload.last_request_time = now
            return [self._request(upload.expected, upload.sender)]
        return []

    def _on_count(
        self, count: int, sender: Endpoint, now: float, booting: bool
    ) -> list[MessageSpec]:
        if self._upload is not None and self._upload.sender != sender:
            return [mission_ack(dialect.MAV_MISSION_DENIED, sender)]
        self._upload = None  # the same sender may restart its upload
        if booting or count > self.max_items:
            return [mission_ack(dialect.MAV_MISSION_NO_SPACE, sender)]
        del self._items[max(count, 1) :]
        if count == 0:
            return [mission_ack(ACCEPTED, sender)]
        self._upload = _Upload(sender, count, 0, now, now)
        return [self._request(0, sender)]

    def _on_item(self, item: MissionItem, sender: Endpoint, now: float) -> list[MessageSpec]:
        upload = self._upload
        if upload is None:
            return []  # a late duplicate after the transfer ended: nothing to answer
        if item.seq != upload.expected:
            return [mission_ack(dialect.MAV_MISSION_INVALID_SEQUENCE, sender)]
        if sender != upload.sender:
            return [mission_ack(dialect.MAV_MISSION_DENIED, sender)]
        problem = item_problem(item)
        if problem != ACCEPTED:
            self._upload = None
            logger.info("item %d refused: %s", item.seq, mission_result_name(problem))
            return [mission_ack(problem, sender)]
        item = ardupilot_frame(item)
        if item.seq < len(self._items):
            self._items[item.seq] = item
        else:
            self._items.append(item)
        upload.expected += 1
        upload.last_item_time = upload.last_request_time = now
        if upload.expected == upload.count:
            self._upload = None
            return [mission_ack(ACCEPTED, sender)]
        return [self._request(upload.expected, sender)]

    def _on_request(self, seq: int, sender: Endpoint, as_int: bool) -> list[MessageSpec]:
        if self._upload is not None:
            return [mission_ack(dialect.MAV_MISSION_DENIED, sender)]
        items = self.items
        if not 0 <= seq < len(items):
            return [
                mission_count(len(items), sender),
                mission_ack(dialect.MAV_MISSION_INVALID_SEQUENCE, sender),
            ]
        encode = mission_item_int if as_int else mission_item_float
        return [encode(items[seq], sender)]


def home_item(lat_e7: int, lon_e7: int, alt_amsl_m: float) -> MissionItem:
    """Seq 0 as ArduPilot reads it back: the home, a NAV_WAYPOINT in frame GLOBAL (AMSL)."""
    return MissionItem(
        seq=0,
        frame=MavFrame.GLOBAL,
        command=MavCmd.NAV_WAYPOINT,
        x=lat_e7,
        y=lon_e7,
        z=alt_amsl_m,
    )
