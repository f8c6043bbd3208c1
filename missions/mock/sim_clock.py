"""Simulated time for mock vehicles, advanced in lock step so that none of them starves.

Mocks advance their simulation in whole steps of ``step_s``. A vehicle may begin step k
when

1. every vehicle sharing the clock has finished step k - 1 (lock step: their timestamps
   agree to the step, whatever the machine's load does to their threads), and
2. the paced wall clock has reached it, ``k * step_s <= speedup * (wall time running)``,
   and the clock is not held (:meth:`SimClock.held`).

A vehicle that may not begin its next step handles its I/O meanwhile, and each step is
followed by a look at its socket. A loaded machine therefore slows simulated time down, for
every vehicle alike, instead of starving message handling (a loop that caught up to the
present without reading its socket would stop answering when it fell behind).
When the simulation lags the paced clock by more than ``max_lag_steps``, the pacing drops
the debt: simulated time then runs late, but never sprints to catch up, because a sprint
would stretch the wall-clock latency of a ground station's commands, in simulated time, by
the sprint's factor.
"""

from __future__ import annotations

import itertools
import math
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager

from flycrane.errors import FieldProblem, InputError

#: How long a vehicle waiting for its peers looks at its socket before checking again [s]:
#: short against a step at the highest speed-ups the tests use (20 ms / 20 = 1 ms).
PEER_POLL_S = 0.0005


class SimClock:
    """Shared simulated time (module docstring).

    Parameters
    ----------
    speedup : float
        Simulated seconds per wall-clock second, at most.
    step_s : float
        The simulation step [s of simulated time].
    epoch_utc : float, optional
        POSIX time [s] at simulated time 0 (default: now).
    max_lag_steps : int
        Lag behind the paced clock beyond which the pacing forgets the debt.
    """

    def __init__(
        self,
        speedup: float = 1.0,
        step_s: float = 0.02,
        epoch_utc: float | None = None,
        max_lag_steps: int = 5,
    ) -> None:
        problems = [
            FieldProblem(name, f"must be finite and > 0, got {value}")
            for name, value in (("speedup", speedup), ("step_s", step_s))
            if not 0 < value < math.inf
        ]
        if max_lag_steps < 1:
            problems.append(FieldProblem("max_lag_steps", f"must be >= 1, got {max_lag_steps}"))
        if problems:
            raise InputError(problems, source="SimClock")
        self.speedup = float(speedup)
        self.step_s = float(step_s)
        self.epoch_utc = time.time() if epoch_utc is None else float(epoch_utc)
        self.max_lag_steps = max_lag_steps
        self._lock = threading.Lock()
        self._epoch_monotonic = time.monotonic()
        self._held_since: float | None = None
        self._stop_step: int | None = None  # no vehicle begins a later step (held(at=...))
        self._done: dict[int, int] = {}  # vehicle -> last step it finished
        self._ids = itertools.count()
        self._frontier = 0  # the last step every vehicle has finished

    # --- time ---------------------------------------------------------------------------

    def _paced(self, wall: float) -> int:
        """The last step the paced clock allows at monotonic time ``wall``."""
        since = (self._held_since if self._held_since is not None else wall) - (
            self._epoch_monotonic
        )
        return int(since * self.speedup / self.step_s)

    def now(self) -> float:
        """Simulated seconds since the epoch: the last step every vehicle has finished (the
        paced clock when no vehicle runs)."""
        with self._lock:
            if not self._done:
                return self._paced(time.monotonic()) * self.step_s
            return self._frontier * self.step_s

    def _run_to(self, step: int, timeout_s: float) -> None:
        """Let the vehicles finish ``step`` and no more; wait until they have."""
        with self._lock:
            if step < self._frontier:
                now = self._frontier * self.step_s
                raise ValueError(f"{step * self.step_s:.3f} s is past: it is {now:.3f} s")
            self._stop_step = step
        deadline = time.monotonic() + timeout_s
        while self.now() < step * self.step_s - self.step_s / 2:
            if time.monotonic() > deadline:
                with self._lock:
                    self._stop_step = None
                raise TimeoutError(f"simulated time did not reach {step * self.step_s:.3f} s")
            time.sleep(PEER_POLL_S)

    # --- vehicles -----------------------------------------------------------------------

    def join(self) -> tuple[int, int]:
        """Register a vehicle: its id and the step it has (notionally) finished."""
        with self._lock:
            vehicle = next(self._ids)
            if self._done:
                first = max(self._done.values())
            else:
                first = self._paced(time.monotonic())
                self._frontier = first
            self._done[vehicle] = first
            return vehicle, first

    def leave(self, vehicle: int) -> None:
        """Unregister a vehicle (its peers stop waiting for it)."""
        with self._lock:
            self._done.pop(vehicle, None)
            self._frontier = min(self._done.values(), default=self._frontier)

    def may_begin(self, vehicle: int, step: int) -> float:
        """0 if ``vehicle`` may begin ``step`` now; else how long to wait before asking
        again [s of wall time]."""
        with self._lock:
            if step > self._frontier + 1 or (
                self._stop_step is not None and step > self._stop_step
            ):
                return PEER_POLL_S
            wall = time.monotonic()
            paced = self._paced(wall)
            if self._held_since is None and paced - self._frontier > self.max_lag_steps:
                # forget the debt (module docstring): pace from the frontier on
                self._epoch_monotonic += (paced - self._frontier - 1) * self.step_s / self.speedup
                paced = self._frontier + 1  # not recomputed: rounding could make it frontier
            if step <= paced:
                return 0.0
            if self._held_since is not None:
                return PEER_POLL_S
            due = self._epoch_monotonic + step * self.step_s / self.speedup
            return max(due - wall, 0.0)

    def finished(self, vehicle: int, step: int) -> None:
        """``vehicle`` has finished ``step``."""
        with self._lock:
            self._done[vehicle] = step
            self._frontier = min(self._done.values())

    @contextmanager
    def held(self, at: float | None = None, timeout_s: float = 10.0) -> Iterator[float]:
        """Stand still inside the block, then run on from where time stopped: everything
        the vehicles handle meanwhile happens at one simulated instant (yielded, [s]).

        With ``at``, first run on to that simulated time [s] (rounded to a step; not before
        now) and stand still there: a ground station's commands at an exact simulated time,
        e.g. a release deliberately late. ``timeout_s`` bounds the wall-clock wait for it.
        """
        if at is not None:
            self._run_to(round(at / self.step_s), timeout_s)
        with self._lock:
            if self._held_since is not None:
                raise RuntimeError("the clock is already held")
            self._held_since = time.monotonic()
        try:
            yield self.now()
        finally:
            with self._lock:
                assert self._held_since is not None
                self._epoch_monotonic += time.monotonic() - self._held_since
                self._held_since = None
                self._stop_step = None
