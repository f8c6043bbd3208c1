"""Commands around a mission: position streams, arming, and one common start.

COMMAND_LONG is sent and re-sent per :class:`~missions.mavlink.policy.RetryPolicy` until its
COMMAND_ACK arrives; a MAV_RESULT other than ACCEPTED raises :class:`CommandRejectedError`.
Re-sending is safe for the commands used here: arming an armed vehicle and starting a
running mission are both accepted without effect by ArduCopter.

Starting several vehicles: one MISSION_START sent to all at once starts them together
(design.md section 9). :func:`start_missions` builds the command
for every vehicle first and then sends them back to back (one packing and one socket write
each, tens of microseconds), so the vehicles receive it within a fraction of a millisecond
of each other on a local network (the spread is measured and reported); only a vehicle
that did not acknowledge is sent it again, and the report says which.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Sequence
from dataclasses import dataclass

from missions.export.items import MavCmd
from missions.mavlink.errors import (
    CommandRejectedError,
    FleetError,
    MavlinkError,
    MavlinkTimeoutError,
)
from missions.mavlink.messages import (
    MessageSpec,
    command_long,
    command_result_name,
    dialect,
    message_interval_params,
    mission_set_current,
    request_data_stream,
)
from missions.mavlink.policy import RetryPolicy
from missions.mavlink.transport import Inbox, VehicleLink

logger = logging.getLogger(__name__)

ACCEPTED = dialect.MAV_RESULT_ACCEPTED
IN_PROGRESS = dialect.MAV_RESULT_IN_PROGRESS


def _await_ack(link: VehicleLink, inbox: Inbox, command: int, until: float) -> bool:
    """True on ACCEPTED before monotonic time ``until``, False on silence; raises on refusal."""
    while (left := until - time.monotonic()) > 0:
        ack = inbox.get(left)
        if ack is None or ack.command != command or ack.result == IN_PROGRESS:
            continue
        if ack.result == ACCEPTED:
            return True
        raise CommandRejectedError(link.name, command, ack.result, command_result_name(ack.result))
    return False


def send_command(
    link: VehicleLink, command: int, params: tuple[float, ...], policy: RetryPolicy
) -> None:
    """Send COMMAND_LONG ``command`` with ``params`` until acknowledged.

    Raises
    ------
    CommandRejectedError
        With the MAV_RESULT of a refusal.
    MavlinkTimeoutError
        Without an answer for ``policy.step_timeout_s()``.
    """
    with link.subscribe(("COMMAND_ACK",)) as inbox:
        for attempt in range(policy.retries + 1):
            link.send(command_long(command, link.target, params, confirmation=min(attempt, 255)))
            if _await_ack(link, inbox, command, time.monotonic() + policy.request_timeout_s):
                return
    raise MavlinkTimeoutError(
        link.name, f"COMMAND_ACK for command {command}", policy.step_timeout_s()
    )


def request_position_stream(link: VehicleLink, rate_hz: float, policy: RetryPolicy) -> None:
    """Ask for GLOBAL_POSITION_INT at ``rate_hz`` [Hz] and wait until one arrives.

    MAV_CMD_SET_MESSAGE_INTERVAL first; if the vehicle refuses it or does not answer, the
    older REQUEST_DATA_STREAM (MAV_DATA_STREAM_POSITION, which has no acknowledgement).
    Periodic MISSION_CURRENT is asked for at the same rate, best effort (a vehicle also
    sends it when the current item changes).

    Raises
    ------
    MavlinkTimeoutError
        If no GLOBAL_POSITION_INT arrives within ``policy.step_timeout_s()`` of the request.
    """
    interval_s = 1.0 / rate_hz
    with link.subscribe(("GLOBAL_POSITION_INT",)) as inbox:
        try:
            send_command(
                link,
                dialect.MAV_CMD_SET_MESSAGE_INTERVAL,
                message_interval_params("GLOBAL_POSITION_INT", interval_s),
                policy,
            )
        except MavlinkError as error:
            logger.info(
                "%s: SET_MESSAGE_INTERVAL failed (%s), REQUEST_DATA_STREAM instead",
                link.name,
                error,
            )
            link.send(
                request_data_stream(
                    dialect.MAV_DATA_STREAM_POSITION, max(1, round(rate_hz)), link.target
                )
            )
        try:
            send_command(
                link,
                dialect.MAV_CMD_SET_MESSAGE_INTERVAL,
                message_interval_params("MISSION_CURRENT", interval_s),
                policy,
            )
        except MavlinkError as error:
            logger.info("%s: no periodic MISSION_CURRENT: %s", link.name, error)
        if inbox.get(policy.step_timeout_s()) is None:
            raise MavlinkTimeoutError(
                link.name, "GLOBAL_POSITION_INT after the stream request", policy.step_timeout_s()
            )


def arm(link: VehicleLink, policy: RetryPolicy) -> None:
    """Arm the vehicle (MAV_CMD_COMPONENT_ARM_DISARM, param1 = 1)."""
    send_command(link, dialect.MAV_CMD_COMPONENT_ARM_DISARM, (1.0,), policy)


@dataclass(frozen=True)
class StartReport:
    """How one common MISSION_START went out.

    ``spread_s`` is the time between the first and the last first-send [s]; ``resent``
    names the vehicles that needed a second send (their start is later by at least one
    request timeout).
    """

    vehicles: tuple[str, ...]
    spread_s: float
    resent: tuple[str, ...]


def _send_back_to_back(
    links: Sequence[VehicleLink],
    specs: Sequence[MessageSpec],
    send_at: Sequence[float] | None = None,
) -> list[float]:
    """Send each vehicle its message, all built beforehand so that the sends are
    microseconds apart (or each at its ground monotonic time ``send_at``); the ground's
    monotonic time of each send [s]."""
    sent = [0.0] * len(links)
    order = sorted(range(len(links)), key=lambda k: send_at[k] if send_at else 0.0)
    for k in order:
        if send_at is not None:
            time.sleep(max(send_at[k] - time.monotonic(), 0.0))
        links[k].send(specs[k])
        sent[k] = time.monotonic()
    return sent


def start_missions(links: Sequence[VehicleLink], policy: RetryPolicy) -> StartReport:
    """Send MAV_CMD_MISSION_START to every vehicle at once (module docstring).

    Raises
    ------
    FleetError
        If any vehicle refused or never acknowledged (the others were started: the caller
        must decide whether to abort them).
    """
    command = int(MavCmd.MISSION_START)
    inboxes = [link.subscribe(("COMMAND_ACK",)) for link in links]
    try:
        sent_at = _send_back_to_back(links, [command_long(command, link.target) for link in links])
        pending = dict(enumerate(links))
        failures: dict[str, MavlinkError] = {}
        resent: set[str] = set()
        for attempt in range(policy.retries + 1):
            until = time.monotonic() + policy.request_timeout_s
            for index, link in list(pending.items()):
                try:
                    if _await_ack(link, inboxes[index], command, until):
                        del pending[index]
                except CommandRejectedError as error:
                    failures[link.name] = error
                    del pending[index]
            if not pending or attempt == policy.retries:
                break
            for link in pending.values():
                logger.warning("%s: MISSION_START not acknowledged, sending again", link.name)
                link.send(command_long(command, link.target, confirmation=attempt + 1))
                resent.add(link.name)
        for link in pending.values():
            failures[link.name] = MavlinkTimeoutError(
                link.name, "COMMAND_ACK for MISSION_START", policy.step_timeout_s()
            )
    finally:
        for inbox in inboxes:
            inbox.close()
    names = tuple(link.name for link in links)
    if failures:
        raise FleetError("start", failures, tuple(n for n in names if n not in failures))
    return StartReport(names, sent_at[-1] - sent_at[0], tuple(sorted(resent)))


def set_message_interval(
    link: VehicleLink, name: str, interval_s: float, policy: RetryPolicy
) -> None:
    """Ask for message ``name`` every ``interval_s`` [s of vehicle time] (acknowledged)."""
    send_command(
        link,
        dialect.MAV_CMD_SET_MESSAGE_INTERVAL,
        message_interval_params(name, interval_s),
        policy,
    )


@dataclass(frozen=True)
class ReleaseReport:
    """How one synchronized release went out: MISSION_SET_CURRENT to every vehicle.

    ``sent_s`` is the ground's monotonic time of each first send [s], ``confirmed_s`` of
    the MISSION_CURRENT confirming the new item, per vehicle in link order.
    """

    vehicles: tuple[str, ...]
    seq: int
    sent_s: tuple[float, ...]
    confirmed_s: tuple[float, ...]

    @property
    def spread_s(self) -> float:
        """Between the first and the last send [s of ground time]."""
        return max(self.sent_s) - min(self.sent_s)


def release(
    links: Sequence[VehicleLink],
    seq: int,
    policy: RetryPolicy,
    send_at: Sequence[float] | None = None,
) -> ReleaseReport:
    """Release every vehicle at once from a hold into item ``seq`` (design.md section 9).

    MISSION_SET_CURRENT has no acknowledgement of its own: the vehicle confirms it with a
    MISSION_CURRENT naming ``seq``. The messages are built first and then sent back to
    back (microseconds apart), or each at its ground monotonic time ``send_at``; a vehicle
    that did not confirm within a request timeout of the last send is *not* sent it
    again: a late second release would start it a timeout after the others, which is what
    this procedure exists to prevent.

    Raises
    ------
    FleetError
        Naming every vehicle that did not confirm (the others were released: the caller
        must stop them).
    """
    inboxes = [link.subscribe(("MISSION_CURRENT",)) for link in links]
    try:
        specs = [mission_set_current(seq, link.target) for link in links]
        sent = _send_back_to_back(links, specs, send_at)
        until = time.monotonic() + policy.request_timeout_s
        confirmed: list[float | None] = []
        for inbox in inboxes:
            at = None
            while at is None and (left := until - time.monotonic()) > 0:
                msg = inbox.get(left)
                if msg is not None and msg.seq == seq:
                    at = time.monotonic()
            confirmed.append(at)
    finally:
        for inbox in inboxes:
            inbox.close()
    names = tuple(link.name for link in links)
    missing = {
        link.name: MavlinkTimeoutError(
            link.name, f"MISSION_CURRENT {seq} after MISSION_SET_CURRENT", policy.request_timeout_s
        )
        for link, at in zip(links, confirmed, strict=True)
        if at is None
    }
    if missing:
        raise FleetError("release", missing, tuple(n for n in names if n not in missing))
    return ReleaseReport(names, seq, tuple(sent), tuple(c for c in confirmed if c is not None))
