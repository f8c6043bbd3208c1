"""The retry policy of every request the ground side makes, written down in one object.

How the numbers are used (``transfer.py``, ``commands.py``, ``transport.py``):

- Each request (MISSION_COUNT, one MISSION_ITEM_INT answer awaited as the next
  MISSION_REQUEST, MISSION_REQUEST_LIST, MISSION_REQUEST_INT, MISSION_CLEAR_ALL, a
  COMMAND_LONG) waits ``request_timeout_s`` for its answer and is sent again on silence, at
  most ``retries`` times; then :class:`~missions.mavlink.errors.MavlinkTimeoutError` names
  the stage and the total wait, ``request_timeout_s * (retries + 1)``
  (:meth:`RetryPolicy.step_timeout_s`). Any answer from the vehicle restarts the count.
- A whole transfer (upload or download of one mission to one vehicle) ends by
  ``deadline_s`` whatever happens, so a vehicle that keeps answering but never finishes
  (e.g. re-requesting the same item forever) cannot hang the caller.
- ``MAV_MISSION_NO_SPACE`` in answer to MISSION_COUNT is what ArduCopter says while it boots
  (:mod:`missions.autopilots.ardupilot`), so during the first ``no_space_retry_s`` of a
  transfer the count is sent again every ``no_space_backoff_s``; after that NO_SPACE is
  final (a mission really too large for the vehicle).
- The first HEARTBEAT is awaited ``heartbeat_timeout_s``, while the ground side sends its
  own GCS heartbeat every ``gcs_heartbeat_interval_s`` (a vehicle listening on UDP only
  learns where to send once it has heard from us).

Defaults: 1.5 s per request and 5 resends (the figures QGroundControl uses for mission
items), 60 s per transfer, NO_SPACE retried every 1 s for 20 s (ArduCopter SITL refuses
missions for a few seconds after its first heartbeat), 5 s for the first heartbeat (five
heartbeat periods). Tests pass a faster policy; nothing here is a module global.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, replace

from flycrane.errors import FieldProblem, InputError

#: The shortest deadline :meth:`RetryPolicy.until` gives (a positive one: at an overall
#: deadline a stage still sends its first request once, then times out) [s].
MIN_DEADLINE_S = 1e-3


@dataclass(frozen=True)
class RetryPolicy:
    """Timeouts [s] and retry counts of the ground side of the link (module docstring)."""

    request_timeout_s: float = 1.5
    retries: int = 5
    deadline_s: float = 60.0
    no_space_backoff_s: float = 1.0
    no_space_retry_s: float = 20.0
    heartbeat_timeout_s: float = 5.0
    gcs_heartbeat_interval_s: float = 1.0

    def __post_init__(self) -> None:
        problems = [
            FieldProblem(name, f"must be > 0, got {getattr(self, name)}")
            for name in (
                "request_timeout_s",
                "deadline_s",
                "no_space_backoff_s",
                "heartbeat_timeout_s",
                "gcs_heartbeat_interval_s",
            )
            if not getattr(self, name) > 0
        ]
        if self.retries < 0:
            problems.append(FieldProblem("retries", f"must be >= 0, got {self.retries}"))
        if self.no_space_retry_s < 0:
            problems.append(
                FieldProblem("no_space_retry_s", f"must be >= 0, got {self.no_space_retry_s}")
            )
        if problems:
            raise InputError(problems, source="RetryPolicy")

    def step_timeout_s(self) -> float:
        """Longest silence one request is waited for, resends included [s]."""
        return self.request_timeout_s * (self.retries + 1)

    def until(self, ends: float | None) -> RetryPolicy:
        """This policy with ``deadline_s`` cut to the time left before ``ends`` (a
        ``time.monotonic()`` value; None: unchanged), so that stages run one after another
        (connect, upload, read-back, parameters) all end by one overall deadline."""
        if ends is None:
            return self
        left = max(ends - time.monotonic(), MIN_DEADLINE_S)
        return replace(self, deadline_s=min(self.deadline_s, left))
