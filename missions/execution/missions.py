"""The missions executor: the autopilots fly their own missions; the ground watches the team.

Waypoint missions keep each drone on its own clock after the release, so the ground cannot
steer them in step; what it can do is the team failsafe (:mod:`.team`): released together
(MISSION_SET_CURRENT back to back, :func:`missions.mavlink.commands.release`), the three
are watched, and on the first fault of any drone all three are switched to GUIDED, where
ArduCopter brakes to its stopping point and holds. A drone that left AUTO on its own (a
failsafe's LAND, a pilot's switch) is not commanded back; the others stop beside it.

Faults are judged as in the other executors but for the distance to a target: the
missions' timing is ArduCopter's (:mod:`missions.autopilots`), not the group clock, so
a drone's distance from the trajectory at the group clock's time is no fault here.
"""

from __future__ import annotations

import math
import time
from collections.abc import Sequence

from missions.autopilots.ardupilot import COPTER_MODES
from missions.execution.executor import Executor
from missions.mavlink.commands import ReleaseReport, release
from missions.mavlink.guided import set_mode_message

#: The release goes out this far ahead of the present [s of common time].
RELEASE_LEAD_S = 0.3


class MissionsExecutor(Executor):
    """Releases the missions and stops all three on a fault (module docstring)."""

    mode = "missions"
    expected_mode = COPTER_MODES["AUTO"]
    #: the autopilots fly from their own hold: the clock only times the record and the
    #: faults after the release
    default_start_delay = 1.0

    def __init__(self, *args, release_seq: int, **kwargs) -> None:  # type: ignore[no-untyped-def]
        super().__init__(*args, **kwargs)
        self.monitor.limits = type(self.monitor.limits)(
            link_timeout=self.monitor.limits.link_timeout,
            stray_distance=math.inf,
            min_fix_type=self.monitor.limits.min_fix_type,
        )
        self.release_seq = release_seq
        self.report: ReleaseReport | None = None
        self._braked = False

    def engage(self, timeout: float, delays: Sequence[float] = (0.0, 0.0, 0.0)) -> None:
        """Release the three at one common time (plus ``delays`` [s], which hold a drone
        back: a deliberately perturbed flight).

        Vehicles that share GPS time and hear the ground at once are released together by
        messages sent back to back. Simulators each keep their own clock, started when
        each booted: the same wall instant is a different instant on each. So each release
        goes out when its vehicle's own clock reaches the common release time (the
        vehicles' clocks, :mod:`.vehicles`); vehicles on one clock get them back to back."""
        now = time.monotonic()
        # A clock runs on whether its vehicle is heard or not: a stale last message is a
        # late one, not a stopped clock (what caps the estimate for steering targets).
        presents = [vehicle.common_time(now, capped=False) for vehicle in self.vehicles]
        known = [p for p in presents if p is not None]
        if not known:
            raise RuntimeError("no vehicle's clock is known")
        when = max(known) + RELEASE_LEAD_S
        due = []
        for k, present in enumerate(presents):
            lag = 0.0 if present is None else when - present
            due.append((now + (lag + delays[k]) / self.speedup, k))
        send_at = [at for at, _ in sorted(due, key=lambda d: d[1])]
        self.report = release(self.links, self.release_seq, self.retry, send_at)

    def _command(self, t: float) -> None:
        if self._stopping and not self._braked:
            guided = COPTER_MODES["GUIDED"]
            for k, link in enumerate(self.links):
                if k not in self.cut:
                    link.send(set_mode_message(guided, link.target))
            self._braked = True
