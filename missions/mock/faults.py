"""Fault injection for the mock autopilot: a lossy, duplicating, or silent link.

Each decision draws from one seeded ``random.Random``, so a test that fails replays with the
same losses. The faults act on whole MAVLink messages, as a radio link loses whole frames.
"""

from __future__ import annotations

import random
from dataclasses import dataclass

from flycrane.errors import FieldProblem, InputError


@dataclass(frozen=True)
class FaultInjection:
    """Shares [0, 1] of messages to drop or to deliver twice, per direction.

    ``unresponsive`` makes the vehicle ignore everything it receives while it keeps sending
    heartbeats: a vehicle whose link works but which never answers.
    """

    drop_incoming: float = 0.0
    drop_outgoing: float = 0.0
    duplicate_incoming: float = 0.0
    duplicate_outgoing: float = 0.0
    unresponsive: bool = False
    seed: int = 0

    def __post_init__(self) -> None:
        problems = [
            FieldProblem(name, f"must be in [0, 1], got {getattr(self, name)}")
            for name in (
                "drop_incoming",
                "drop_outgoing",
                "duplicate_incoming",
                "duplicate_outgoing",
            )
            if not 0.0 <= getattr(self, name) <= 1.0
        ]
        if problems:
            raise InputError(problems, source="FaultInjection")


class FaultyChannel:
    """How many copies of each message get through (0, 1 or 2), per :class:`FaultInjection`."""

    def __init__(self, faults: FaultInjection) -> None:
        self.faults = faults
        self._rng = random.Random(faults.seed)

    def _copies(self, drop: float, duplicate: float) -> int:
        if drop > 0 and self._rng.random() < drop:
            return 0
        if duplicate > 0 and self._rng.random() < duplicate:
            return 2
        return 1

    def incoming_copies(self) -> int:
        """Copies of a received message to handle (0 for an unresponsive vehicle)."""
        if self.faults.unresponsive:
            return 0
        return self._copies(self.faults.drop_incoming, self.faults.duplicate_incoming)

    def outgoing_copies(self) -> int:
        """Copies of a message to send."""
        return self._copies(self.faults.drop_outgoing, self.faults.duplicate_outgoing)
