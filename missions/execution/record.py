"""What an execution did, on common time: ``execution.json`` beside a flight's logs, written
by the executor (:mod:`.executor`) and read back by the flight report."""

from __future__ import annotations

import json
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

from flycrane.errors import FieldProblem, InputError
from missions.execution.group_clock import GroupClock, Segment


@dataclass
class ExecutionRecord:
    """What an execution did, on common time: its clock, its faults, its stop
    (``execution.json`` beside a flight's logs)."""

    mode: str
    start: float  #: common time of plan time 0 [s]
    duration: float  #: the plan's [s]
    segments: list[dict[str, float]] = field(default_factory=list)
    faults: list[dict[str, Any]] = field(default_factory=list)
    commanded_stop_at: float | None = None  #: when the team stop went out [common s]
    stopped_at: float | None = None  #: when the clock's rate reached 0 after it
    offsets: list[float] = field(default_factory=list)  #: per drone, common - boot [s]
    #: per drone, the longest it went unheard while its link counted [s of common time]:
    #: what a ``link_timeout`` must stay above on this link and host
    silences: list[float] = field(default_factory=lambda: [0.0, 0.0, 0.0])
    frames: list[dict[str, float]] = field(default_factory=list)
    ticks: int = 0

    def as_dict(self) -> dict[str, Any]:
        return asdict(self)

    @classmethod
    def read(cls, path: Path) -> ExecutionRecord:
        """From an ``execution.json``.

        Raises
        ------
        InputError
            No such file, or not an execution record of this version (field ``execution``).
        """
        try:
            return cls(**json.loads(path.read_text(encoding="utf-8")))
        except (OSError, ValueError, TypeError) as error:
            raise InputError([FieldProblem("execution", f"{path}: {error}")]) from None

    def clock(self) -> GroupClock:
        """The group clock as it ran."""
        segments = [Segment(**s) for s in self.segments]
        return GroupClock(self.start, self.duration, segments)
