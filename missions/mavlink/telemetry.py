"""Record what the vehicles report while they fly: positions, current item, items reached.

Each record keeps two clocks: ``received_s``, the ground's ``time.monotonic()`` at receipt
(common to all vehicles of one recorder), and for positions the vehicle's own
``time_boot_ms`` (free of network delay, but each vehicle has its own boot time).
"""

from __future__ import annotations

import threading
import time
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

from missions.mavlink.transport import VehicleLink

RECORDED = ("GLOBAL_POSITION_INT", "MISSION_CURRENT", "MISSION_ITEM_REACHED")


@dataclass(frozen=True)
class PositionSample:
    """One GLOBAL_POSITION_INT, in the message's units."""

    received_s: float  #: ground monotonic time [s]
    time_boot_ms: int  #: vehicle time [ms]
    lat_e7: int  #: [1e-7 deg]
    lon_e7: int  #: [1e-7 deg]
    alt_mm: int  #: AMSL [mm]
    relative_alt_mm: int  #: above home [mm]
    velocity_ned_cms: tuple[int, int, int]  #: north, east, down [cm/s]


@dataclass(frozen=True)
class SeqEvent:
    """A MISSION_CURRENT or MISSION_ITEM_REACHED: which item, when received."""

    received_s: float  #: ground monotonic time [s]
    seq: int


@dataclass(frozen=True)
class VehicleTelemetry:
    """Everything recorded from one vehicle, in arrival order."""

    vehicle: str
    positions: tuple[PositionSample, ...]
    current: tuple[SeqEvent, ...]
    reached: tuple[SeqEvent, ...]


class _Buffer:
    def __init__(self) -> None:
        self.positions: list[PositionSample] = []
        self.current: list[SeqEvent] = []
        self.reached: list[SeqEvent] = []


class TelemetryRecorder:
    """Records :data:`RECORDED` messages from every link while started (or inside ``with``).

    It listens on the links' reader threads, so it opens no socket or thread of its own.
    """

    def __init__(self, links: Sequence[VehicleLink]) -> None:
        self._links = tuple(links)
        self._lock = threading.Lock()
        self._buffers = {link.name: _Buffer() for link in self._links}
        self._callbacks = {link.name: self._callback_for(link.name) for link in self._links}
        self._started = False

    def _callback_for(self, name: str) -> Any:
        buffer = self._buffers[name]

        def record(msg: Any) -> None:
            now = time.monotonic()
            kind = msg.get_type()
            with self._lock:
                if kind == "GLOBAL_POSITION_INT":
                    buffer.positions.append(
                        PositionSample(
                            now,
                            msg.time_boot_ms,
                            msg.lat,
                            msg.lon,
                            msg.alt,
                            msg.relative_alt,
                            (msg.vx, msg.vy, msg.vz),
                        )
                    )
                elif kind == "MISSION_CURRENT":
                    buffer.current.append(SeqEvent(now, msg.seq))
                else:
                    buffer.reached.append(SeqEvent(now, msg.seq))

        return record

    def start(self) -> TelemetryRecorder:
        if not self._started:
            for link in self._links:
                link.add_listener(RECORDED, self._callbacks[link.name])
            self._started = True
        return self

    def stop(self) -> None:
        if self._started:
            for link in self._links:
                link.remove_listener(self._callbacks[link.name])
            self._started = False

    def __enter__(self) -> TelemetryRecorder:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.stop()

    def snapshot(self) -> dict[str, VehicleTelemetry]:
        """What has been recorded so far, by vehicle name."""
        with self._lock:
            return {
                name: VehicleTelemetry(name, tuple(b.positions), tuple(b.current), tuple(b.reached))
                for name, b in self._buffers.items()
            }
