"""Watching SITL vehicles from the ground: a message from each, each simulator's pace, each
drone steady at its hold."""

from __future__ import annotations

import logging
import math
import time
from collections import deque
from collections.abc import Callable, Sequence
from typing import Any

from missions.export.items import MissionItem
from missions.geodesy import DEGREE_UNIT, ardupilot_altitude, enu_from_geodetic
from missions.mavlink.transport import VehicleLink
from missions.options import GeodeticOrigin
from missions.position_error import PositionErrorModel
from missions.sitl.errors import SitlError

logger = logging.getLogger(__name__)


def wait_for(
    links: Sequence[VehicleLink],
    types: tuple[str, ...],
    done: Callable[[VehicleLink, Any], bool],
    timeout_s: float,
    what: str,
) -> None:
    """Wait until ``done(link, msg)`` held for a message from every link."""
    pending = {link.name for link in links}
    inboxes = {link.name: link.subscribe(types) for link in links}
    deadline = time.monotonic() + timeout_s
    try:
        while pending:
            if time.monotonic() > deadline:
                raise SitlError(f"{what}: {sorted(pending)} not within {timeout_s:.0f} s")
            for link in links:
                if link.name in pending:
                    msg = inboxes[link.name].get(0.01)
                    if msg is not None and done(link, msg):
                        pending.discard(link.name)
    finally:
        for inbox in inboxes.values():
            inbox.close()


class RateMeter:
    """Simulated seconds per wall second of every vehicle, from SYSTEM_TIME."""

    def __init__(self, links: Sequence[VehicleLink]) -> None:
        self.first: dict[str, tuple[float, float]] = {}
        self.last: dict[str, tuple[float, float]] = {}
        for link in links:
            link.add_listener(("SYSTEM_TIME",), self._listener(link.name))

    def _listener(self, name: str) -> Callable[[Any], None]:
        def on(msg: Any) -> None:
            sample = (time.monotonic(), msg.time_boot_ms / 1000.0)
            self.first.setdefault(name, sample)
            self.last[name] = sample

        return on

    def restart(self) -> None:
        """Measure from now on (after a change of pace)."""
        self.first.clear()
        self.last.clear()

    def rates(self) -> dict[str, float]:
        rates = {}
        for name, (wall0, boot0) in self.first.items():
            wall1, boot1 = self.last[name]
            rates[name] = (boot1 - boot0) / (wall1 - wall0) if wall1 > wall0 else 0.0
        return rates


class HoldWatch:
    """The latest MISSION_CURRENT and time of every vehicle, since when it has been at that
    item, and since when it has been steady at its hold: slower than ``settle_speed``
    [m/s] and its estimate within ``settle_distance`` [m] of ``holds``; and how fast and
    how far off it was at worst over the last ``window_s`` [s] (reader threads)."""

    def __init__(
        self,
        links: Sequence[VehicleLink],
        holds: Sequence[MissionItem],
        settle_speed: float,
        settle_distance: float,
        window_s: float,
    ) -> None:
        self.current = {link.name: -1 for link in links}
        self.current_since = {link.name: 0.0 for link in links}
        self.slow_since: dict[str, float | None] = {link.name: None for link in links}
        self.boot_s = {link.name: 0.0 for link in links}
        self.settle_speed = settle_speed
        self.settle_distance = settle_distance
        self.window_s = window_s
        #: per vehicle: (boot time [s], speed [m/s], horizontal and vertical distance to
        #: its hold [m])
        self.recent: dict[str, deque[tuple[float, float, float, float]]] = {
            link.name: deque() for link in links
        }
        # each hold where ArduPilot flies it: its latitude and longitude, and its altitude
        # above home in whole centimetres (relative_alt is above home too)
        self._holds = {
            link.name: GeodeticOrigin(
                latitude=hold.x * DEGREE_UNIT,
                longitude=hold.y * DEGREE_UNIT,
                altitude=float(ardupilot_altitude(hold.z)),
            )
            for link, hold in zip(links, holds, strict=True)
        }
        self._links = links
        for link in links:
            link.add_listener(("MISSION_CURRENT", "GLOBAL_POSITION_INT"), self._listener(link.name))

    def _listener(self, name: str) -> Callable[[Any], None]:
        def on(msg: Any) -> None:
            if msg.get_type() == "MISSION_CURRENT":
                if msg.seq != self.current[name]:
                    self.current[name] = msg.seq
                    self.current_since[name] = self.boot_s[name]
                    self.slow_since[name] = None
                return
            now = msg.time_boot_ms / 1000.0
            self.boot_s[name] = now
            speed = (msg.vx**2 + msg.vy**2 + msg.vz**2) ** 0.5 / 100.0
            offset = enu_from_geodetic(
                msg.lat * DEGREE_UNIT, msg.lon * DEGREE_UNIT, msg.relative_alt / 1000.0,
                self._holds[name],
            )  # fmt: skip
            distance = math.hypot(*offset)
            recent = self.recent[name]
            recent.append((now, speed, math.hypot(offset[0], offset[1]), abs(offset[2])))
            while recent[0][0] < now - self.window_s:
                recent.popleft()
            if speed > self.settle_speed or distance > self.settle_distance:
                self.slow_since[name] = None
            elif self.slow_since[name] is None:
                self.slow_since[name] = now

        return on

    def steady_for(self, name: str) -> float:
        since = self.slow_since[name]
        return 0.0 if since is None else self.boot_s[name] - since

    def at_current_for(self, name: str) -> float:
        """How long the vehicle has been at its current mission item [s]."""
        return self.boot_s[name] - self.current_since[name]

    def worst(self, name: str) -> tuple[float, float, float]:
        """The vehicle's highest speed [m/s] and its farthest horizontal and vertical
        distances from its hold [m] over the last ``window_s`` (NaN before a message)."""
        recent = list(self.recent[name])
        if not recent:
            return math.nan, math.nan, math.nan
        speed, horizontal, vertical = (max(r[i] for r in recent) for i in (1, 2, 3))
        return speed, horizontal, vertical

    def unsteady_reasons(
        self, model: PositionErrorModel, patience_s: float, settle_s: float
    ) -> tuple[str, ...]:
        """Why the vehicles that never held steady for ``settle_s`` within ``patience_s``
        may not be released: each one farther from its hold over the last ``window_s`` than
        the position-error model's bounds (what the release check judges one instant by).
        One within them is released with a warning: the plan's clearance was made for its
        errors."""
        reasons = []
        for name in self.current:
            if self.steady_for(name) >= settle_s:
                continue
            speed, horizontal, vertical = self.worst(name)
            seen = (
                f"{name}: not steady at its start hold in {patience_s:g} s: up to "
                f"{speed:.2f} m/s, {horizontal:.3f} m across and {vertical:.3f} m up or down "
                f"from it over the last {self.window_s:g} s"
            )
            if not (
                horizontal <= model.common_horizontal + model.relative_horizontal
                and vertical <= model.common_vertical + model.relative_vertical
            ):
                reasons.append(f"{seen}, beyond the position-error model")
            else:
                logger.warning("%s, within the position-error model: released", seen)
        return tuple(reasons)

    def wait(self, condition: Callable[[], bool], timeout_s: float, what: str) -> None:
        deadline = time.monotonic() + timeout_s
        while not condition():
            if time.monotonic() > deadline:
                state = {n: (self.current[n], round(self.steady_for(n), 2)) for n in self.current}
                raise SitlError(f"{what} not within {timeout_s:.0f} s (seq, steady s): {state}")
            time.sleep(0.005)
