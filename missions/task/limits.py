"""What bounds and ends a task's phases: a cancel and the time budget, checked between and
inside the phases of mission building and writing (:mod:`missions.task.build`,
:mod:`missions.task.write`), and the status and reason each ending gives the task."""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from flycrane.errors import FlyCraneError
from missions.task.documents import Status
from missions.trajectory.waypoints import SafetyCheck


class MissionFailure(FlyCraneError):
    """The path cannot be made into missions that keep the load safe; the message says
    why."""


class Cancelled(FlyCraneError):
    """The task was cancelled while its missions were built or written."""


@dataclass(frozen=True)
class PhaseLimits:
    """What stops the mission phases: a cancel (``should_stop``, None: never) or the end of
    their time budget (``deadline`` on :func:`time.monotonic`, None: none; ``budget`` [s]
    for the message)."""

    should_stop: Callable[[], bool] | None = None
    deadline: float | None = None
    budget: float = 0.0

    @classmethod
    def starting_now(cls, should_stop: Callable[[], bool] | None, budget: float) -> PhaseLimits:
        return cls(should_stop, time.monotonic() + budget, budget)

    def check(self, during: str = "its missions were built") -> None:
        """Raises :class:`Cancelled` if the task is to stop, :class:`MissionFailure` past
        the deadline."""
        if self.should_stop is not None and self.should_stop():
            raise Cancelled(f"cancelled while {during}")
        if self.deadline is not None and time.monotonic() > self.deadline:
            raise MissionFailure(
                f"it took longer than its time budget, {self.budget:g} s "
                "(planner.time_budget bounds the planning and, again, the missions' making)"
            )

    def wrap(self, check: SafetyCheck) -> SafetyCheck:
        """``check``, asking first."""

        def checked(q: NDArray[np.float64]) -> NDArray[np.bool_]:
            self.check()
            return check(q)

        return checked


class TaskEnded(Exception):
    """A phase ended the task: its status and reason."""

    def __init__(self, status: Status, reason: str) -> None:
        self.status, self.reason = status, reason


def ending(failure: TaskEnded | MissionFailure | Cancelled) -> tuple[Status, str]:
    """Status and reason of what ended a task before its files were all written."""
    if isinstance(failure, TaskEnded):
        return failure.status, failure.reason
    if isinstance(failure, Cancelled):
        return "cancelled", str(failure)
    return "failed", f"mission generation: {failure}"
