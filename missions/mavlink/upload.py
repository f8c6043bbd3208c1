"""Upload a mission and prove it arrived: upload, read back, compare item by item.

A vehicle ends in one of two states: it holds the verified new mission, or (best effort)
none. ArduPilot writes items as they arrive, so a failed upload leaves a half-written
mission, and a mission that reads back different cannot be trusted either; in both cases
:func:`upload_and_verify` sends MISSION_CLEAR_ALL before re-raising, so that nobody starts a
half mission by mistake. Its outcome is logged, never raised over the original error.
When only the final MISSION_ACK was lost, the read-back (if any) decides: a mission that
reads back identical is on board, whatever happened to the ack.

Seq 0: ArduPilot keeps seq 0 for its home and reads it back as the current home position
(frame GLOBAL, altitude AMSL) whatever was uploaded there, and overwrites it again at
arming. :attr:`Verification.ARDUPILOT` therefore checks that seq 0 exists and compares every
other item, each as sent or as ArduCopter stores it (altitudes in whole centimetres,
NAV_WAYPOINT without acceptance radius: :func:`~.messages.ardupilot_readback`); the home the
vehicle reported is returned in :class:`UploadReport` so the caller can check it against the
mission's origin. :attr:`Verification.ALL_ITEMS` compares seq 0 as
well (vehicles that store it verbatim, e.g. PX4 or MAVSDK's MissionRawServer).

Given the parameters the mission assumes (its ``.parm``), the upload reads each back from
the vehicle and reports every difference (:attr:`UploadReport.parameter_errors`, logged as
warnings): the mission is on board, but its timing holds only with those values.
"""

from __future__ import annotations

import enum
import logging
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

from missions.export.items import DroneMission, MissionItem
from missions.mavlink.errors import (
    FinalAckTimeoutError,
    MavlinkError,
    MissionVerificationError,
    ParameterError,
)
from missions.mavlink.messages import COMPARED_FIELDS, ardupilot_readback, item_difference
from missions.mavlink.params import ParameterCheck, check_parameters
from missions.mavlink.policy import RetryPolicy
from missions.mavlink.transfer import clear_mission, download_mission, upload_mission
from missions.mavlink.transport import VehicleLink

logger = logging.getLogger(__name__)


class Verification(enum.Enum):
    """How an uploaded mission is checked by reading it back (module docstring)."""

    NONE = "none"  #: trust the vehicle's ACCEPTED
    ARDUPILOT = "ardupilot"  #: every item but seq 0 (the vehicle's home), as ArduCopter stores it
    ALL_ITEMS = "all_items"  #: every item


@dataclass(frozen=True)
class UploadReport:
    """A verified upload to one vehicle.

    ``home`` is seq 0 as read back (the vehicle's home for ArduPilot), None without
    verification; ``duration_s`` covers upload and read-back [s]; ``parameters`` the
    vehicle's parameters read back against the mission's ``.parm`` (empty when none was
    given).
    """

    vehicle: str
    system_id: int
    item_count: int
    home: MissionItem | None
    duration_s: float
    parameters: tuple[ParameterCheck, ...] = ()

    @property
    def parameter_errors(self) -> tuple[ParameterError, ...]:
        """The parameters that differ from the mission's (each names vehicle, parameter,
        expected and found value)."""
        return tuple(check.error() for check in self.parameters if not check.ok)


def verify_mission(
    vehicle: str,
    expected: Sequence[MissionItem],
    actual: Sequence[MissionItem],
    verification: Verification,
) -> None:
    """Compare a read-back mission with the uploaded one (see :func:`item_difference`).

    Raises
    ------
    MissionVerificationError
        At the first differing item and field (``field="count"`` if the counts differ).
    """
    if len(expected) != len(actual):
        raise MissionVerificationError(vehicle, None, "count", len(expected), len(actual))
    first = 1 if verification is Verification.ARDUPILOT else 0
    for want, got in zip(expected[first:], actual[first:], strict=True):
        field = item_difference(want, got)
        if field is not None and verification is Verification.ARDUPILOT:
            stored = ardupilot_readback(want)
            other = item_difference(stored, got)
            if other is None:
                continue
            # name the difference from the closer of the two readings
            if COMPARED_FIELDS.index(other) > COMPARED_FIELDS.index(field):
                want, field = stored, other
        if field is not None:
            raise MissionVerificationError(
                vehicle, want.seq, field, getattr(want, field), getattr(got, field)
            )


def _discard(link: VehicleLink, policy: RetryPolicy, ends: float | None = None) -> None:
    """Clear a mission that must not stay on the vehicle (by ``ends``, if given); log, never
    raise."""
    quick = RetryPolicy(
        request_timeout_s=policy.request_timeout_s,
        retries=1,
        deadline_s=policy.request_timeout_s * 2,
    ).until(ends)
    try:
        clear_mission(link, quick)
        logger.warning("%s: mission cleared after the failed upload", link.name)
    except MavlinkError as error:
        logger.error("%s: could not clear the failed upload: %s", link.name, error)


def upload_and_verify(
    link: VehicleLink,
    mission: DroneMission | Sequence[MissionItem],
    policy: RetryPolicy,
    verification: Verification = Verification.ARDUPILOT,
    parameters: Mapping[str, float] | None = None,
    ends: float | None = None,
) -> UploadReport:
    """Upload ``mission`` on ``link`` (heartbeat already received) and verify it; then read
    ``parameters`` (the mission's ``.parm``) back from the vehicle and compare.

    With ``ends`` (a ``time.monotonic()`` value), every stage, the clearing of a failed
    upload included, ends by then (:meth:`RetryPolicy.until`): parameters not read by then
    are reported as not answered.

    Raises
    ------
    MissionTransferError, MavlinkTimeoutError, MissionVerificationError
        After clearing the vehicle's mission (module docstring).
    """
    items = mission.items if isinstance(mission, DroneMission) else tuple(mission)
    started = time.monotonic()
    try:
        try:
            upload_mission(link, items, policy.until(ends))
        except FinalAckTimeoutError:
            if verification is Verification.NONE:
                raise
            logger.warning("%s: final MISSION_ACK lost; the read-back decides", link.name)
        home = None
        if verification is not Verification.NONE:
            stored = download_mission(link, policy.until(ends))
            verify_mission(link.name, items, stored, verification)
            home = stored[0] if stored else None
    except MavlinkError:
        _discard(link, policy, ends)
        raise
    checks = check_parameters(link, parameters, policy.until(ends)) if parameters else ()
    report = UploadReport(
        vehicle=link.name,
        system_id=link.info.system_id,
        item_count=len(items),
        home=home,
        duration_s=time.monotonic() - started,
        parameters=checks,
    )
    for error in report.parameter_errors:
        logger.warning("%s", error)
    return report
