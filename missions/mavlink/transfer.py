"""The ground side of the MAVLink mission protocol on one link: upload, download, clear.

Timeouts, resends, the transfer deadline and the NO_SPACE back-off follow the
:class:`~missions.mavlink.policy.RetryPolicy` passed in (its docstring states the rules).
Protocol choices:

- Upload answers MISSION_REQUEST (ArduCopter) and MISSION_REQUEST_INT alike with
  MISSION_ITEM_INT, and re-sends the last message on silence (MISSION_COUNT until the first
  request, then the last item). The vehicle drives the order; a re-request is answered again.
- Upload succeeds only on MISSION_ACK ACCEPTED after the vehicle requested the last item. A
  stale ACCEPTED arriving earlier (e.g. a duplicated ack of an earlier operation) is
  ignored, never taken for success. If that final ack is lost, re-sending the last item
  does not bring it back (ArduPilot ignores items once the transfer is over), so the
  timeout is a :class:`FinalAckTimeoutError`: a read-back can still prove the mission whole.
- MAV_MISSION_INVALID_SEQUENCE does not end the transfer: ArduPilot sends it for an item it
  did not ask for (typically a duplicate) and keeps the transfer open. Every other result
  ends it with :class:`MissionTransferError`.
- Download requests every item with MISSION_REQUEST_INT (also accepting a MISSION_ITEM
  answer) and closes with MISSION_ACK ACCEPTED.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable, Sequence
from typing import Any, TypeVar

from missions.export.items import MissionItem
from missions.mavlink.errors import (
    FinalAckTimeoutError,
    MavlinkTimeoutError,
    MissionTransferError,
)
from missions.mavlink.messages import (
    MessageSpec,
    dialect,
    item_from_message,
    mission_ack,
    mission_clear_all,
    mission_count,
    mission_item_int,
    mission_request_int,
    mission_request_list,
    mission_result_name,
)
from missions.mavlink.policy import RetryPolicy
from missions.mavlink.transport import Inbox, VehicleLink

logger = logging.getLogger(__name__)

ACCEPTED = dialect.MAV_MISSION_ACCEPTED
T = TypeVar("T")


def _addressed_to_us(link: VehicleLink, msg: Any, mission_type: int) -> bool:
    target = getattr(msg, "target_system", 0)
    return target in (0, link.source.system) and getattr(msg, "mission_type", 0) == mission_type


def upload_mission(
    link: VehicleLink, items: Sequence[MissionItem], policy: RetryPolicy, mission_type: int = 0
) -> None:
    """Upload ``items`` (seq 0..n-1, in order) to the vehicle on ``link``.

    Returns only after the vehicle acknowledged the complete mission with ACCEPTED.

    Raises
    ------
    MissionTransferError
        The vehicle refused (the ack's MAV_MISSION_RESULT, and the last item sent).
    FinalAckTimeoutError
        All items went out but the final MISSION_ACK did not come back.
    MavlinkTimeoutError
        No answer for ``policy.step_timeout_s()``, or the transfer exceeded
        ``policy.deadline_s``.
    ValueError
        If the items' seq are not 0..n-1 in order.
    """
    for position, item in enumerate(items):
        if item.seq != position:
            raise ValueError(f"item at position {position} has seq {item.seq}")
    count = len(items)
    started = time.monotonic()
    deadline = started + policy.deadline_s
    types = ("MISSION_REQUEST", "MISSION_REQUEST_INT", "MISSION_ACK")
    with link.subscribe(types) as inbox:
        last_sent: MessageSpec = mission_count(count, link.target, mission_type)
        link.send(last_sent)
        highest = -1  # highest seq the vehicle asked for
        silences = 0
        while True:
            stage = (
                f"MISSION_REQUEST for item {highest + 1}"
                if highest + 1 < count
                else ("MISSION_ACK")
            )
            now = time.monotonic()
            if now >= deadline:
                raise MavlinkTimeoutError(
                    link.name, f"upload: {stage} (deadline)", policy.deadline_s
                )
            msg = inbox.get(min(policy.request_timeout_s, deadline - now))
            if msg is None:
                silences += 1
                if silences > policy.retries:
                    lost = FinalAckTimeoutError if highest == count - 1 else MavlinkTimeoutError
                    raise lost(link.name, f"upload: {stage}", policy.step_timeout_s())
                logger.info("%s: no %s, re-sending %s", link.name, stage, last_sent[0])
                link.send(last_sent)
                continue
            if not _addressed_to_us(link, msg, mission_type):
                continue
            silences = 0
            if msg.get_type() != "MISSION_ACK":
                if not 0 <= msg.seq < count:
                    logger.warning(
                        "%s: request for item %d of %d ignored", link.name, msg.seq, count
                    )
                    continue
                highest = max(highest, msg.seq)
                last_sent = mission_item_int(items[msg.seq], link.target)
                link.send(last_sent)
                continue
            result = msg.type
            if result == ACCEPTED:
                if highest == count - 1:
                    logger.info(
                        "%s: %d items uploaded in %.2f s",
                        link.name,
                        count,
                        time.monotonic() - started,
                    )
                    return
                logger.warning(
                    "%s: ACCEPTED before item %d was requested: stale, ignored",
                    link.name,
                    count - 1,
                )
            elif result == dialect.MAV_MISSION_INVALID_SEQUENCE:
                logger.info("%s: INVALID_SEQUENCE (a duplicate item), transfer goes on", link.name)
            elif (
                result == dialect.MAV_MISSION_NO_SPACE
                and highest < 0
                and time.monotonic() - started < policy.no_space_retry_s
            ):
                logger.info(
                    "%s: NO_SPACE (vehicle booting?), count again in %.2g s",
                    link.name,
                    policy.no_space_backoff_s,
                )
                time.sleep(min(policy.no_space_backoff_s, max(deadline - time.monotonic(), 0)))
                link.send(last_sent)
            else:
                raise MissionTransferError(
                    link.name,
                    "upload",
                    result,
                    mission_result_name(result),
                    seq=highest if highest >= 0 else None,
                )


def _exchange(
    link: VehicleLink,
    inbox: Inbox,
    request: MessageSpec,
    answer: Callable[[Any], T | None],
    stage: str,
    operation: str,
    policy: RetryPolicy,
    deadline: float,
    mission_type: int,
) -> T:
    """Send ``request`` until ``answer(msg)`` gives a value; error acks end it."""
    link.send(request)
    silences = 0
    while True:
        now = time.monotonic()
        if now >= deadline:
            raise MavlinkTimeoutError(link.name, f"{stage} (deadline)", policy.deadline_s)
        msg = inbox.get(min(policy.request_timeout_s, deadline - now))
        if msg is None:
            silences += 1
            if silences > policy.retries:
                raise MavlinkTimeoutError(link.name, stage, policy.step_timeout_s())
            link.send(request)
            continue
        if not _addressed_to_us(link, msg, mission_type):
            continue
        value = answer(msg)
        if value is not None:
            return value
        if msg.get_type() == "MISSION_ACK" and msg.type != ACCEPTED:
            raise MissionTransferError(
                link.name, operation, msg.type, mission_result_name(msg.type)
            )


def download_mission(
    link: VehicleLink, policy: RetryPolicy, mission_type: int = 0
) -> tuple[MissionItem, ...]:
    """Read the mission stored on the vehicle on ``link``, item by item.

    Raises
    ------
    MissionTransferError, MavlinkTimeoutError
        As :func:`upload_mission`.
    """
    deadline = time.monotonic() + policy.deadline_s
    types = ("MISSION_COUNT", "MISSION_ITEM_INT", "MISSION_ITEM", "MISSION_ACK")
    with link.subscribe(types) as inbox:
        count = _exchange(
            link,
            inbox,
            mission_request_list(link.target, mission_type),
            lambda m: int(m.count) if m.get_type() == "MISSION_COUNT" else None,
            "download: MISSION_COUNT",
            "download",
            policy,
            deadline,
            mission_type,
        )
        items = []
        for seq in range(count):

            def item_of(msg: Any, seq: int = seq) -> MissionItem | None:
                if msg.get_type() in ("MISSION_ITEM_INT", "MISSION_ITEM") and msg.seq == seq:
                    return item_from_message(msg)
                return None

            items.append(
                _exchange(
                    link,
                    inbox,
                    mission_request_int(seq, link.target, mission_type),
                    item_of,
                    f"download: MISSION_ITEM_INT {seq}",
                    "download",
                    policy,
                    deadline,
                    mission_type,
                )
            )
        link.send(mission_ack(ACCEPTED, link.target, mission_type))
    return tuple(items)


def clear_mission(link: VehicleLink, policy: RetryPolicy, mission_type: int = 0) -> None:
    """MISSION_CLEAR_ALL, until the vehicle acknowledges it.

    Raises
    ------
    MissionTransferError, MavlinkTimeoutError
        As :func:`upload_mission`.
    """
    deadline = time.monotonic() + policy.deadline_s
    with link.subscribe(("MISSION_ACK",)) as inbox:
        _exchange(
            link,
            inbox,
            mission_clear_all(link.target, mission_type),
            lambda m: True if m.type == ACCEPTED else None,
            "clear: MISSION_ACK",
            "clear",
            policy,
            deadline,
            mission_type,
        )
