"""Telemetry logs in the ``.tlog`` format ground stations read (QGroundControl, Mission
Planner, MAVProxy, pymavlink's ``mavlogdump``).

A tlog is the MAVLink packets of a link as received, each preceded by its receipt time as
a big-endian unsigned 64-bit count of microseconds since the Unix epoch. :class:`TlogWriter`
listens on a :class:`~missions.mavlink.transport.VehicleLink` and appends every message
from the vehicle. Its clock is given: wall time for a real flight; for a simulator running
``speedup`` times faster than the wall clock, wall time stretched by the speed-up from the
start of the log, piecewise where the simulators change pace (:class:`StretchedClock`), so
that the log replays at the speed of the simulated flight and logs of several simulators
share one time base.
"""

from __future__ import annotations

import struct
import threading
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any, BinaryIO

from missions.mavlink.transport import VehicleLink

#: A clock for log records: POSIX seconds.
Clock = Callable[[], float]


class StretchedClock:
    """POSIX time of a simulation started at ``start_utc`` / ``start_monotonic`` and
    running ``speedup`` times faster than the wall clock, until :meth:`change_pace` gives it
    another speed-up from a moment on (reader threads read it while it changes)."""

    def __init__(self, speedup: float, start_utc: float, start_monotonic: float) -> None:
        self._base = (speedup, start_utc, start_monotonic)

    @property
    def speedup(self) -> float:
        return self._base[0]

    def at(self, monotonic: float) -> float:
        """The simulation's POSIX time at monotonic time ``monotonic`` [s], a moment since
        the last change of pace."""
        speedup, utc, start = self._base
        return utc + (monotonic - start) * speedup

    def change_pace(self, speedup: float, monotonic: float) -> None:
        """Run ``speedup`` times faster than the wall clock from monotonic time
        ``monotonic`` on."""
        self._base = (speedup, self.at(monotonic), monotonic)

    def __call__(self) -> float:
        return self.at(time.monotonic())


def tlog_record(timestamp_s: float, packet: bytes) -> bytes:
    """One tlog record: the time [s since the epoch] as microseconds, then the packet."""
    return struct.pack(">Q", int(timestamp_s * 1e6)) + packet


class TlogWriter:
    """Appends every message a link receives to ``path`` (use ``with``)."""

    def __init__(self, link: VehicleLink, path: Path, clock: Clock = time.time) -> None:
        self.link = link
        self.path = path
        self.clock = clock
        self._lock = threading.Lock()
        self._file: BinaryIO | None = None

    def _write(self, msg: Any) -> None:
        record = tlog_record(self.clock(), bytes(msg.get_msgbuf()))
        with self._lock:
            if self._file is not None:
                self._file.write(record)

    def start(self) -> TlogWriter:
        self._file = open(self.path, "wb")
        self.link.add_listener(None, self._write)
        return self

    def stop(self) -> None:
        self.link.remove_listener(self._write)
        with self._lock:
            if self._file is not None:
                self._file.close()
                self._file = None

    def __enter__(self) -> TlogWriter:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.stop()
