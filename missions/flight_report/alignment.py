"""One time base for three drones whose logs are timed by their own clocks.

Each drone's log is timed by its own clock (``time_boot_ms``), which started when it
booted. The drones are coupled by the load in real time, so the flight is judged on
*mission time*, one clock for the three, placed on each drone's samples by

    mission_time = release_k + (vehicle_time - vehicle_release_k)

where ``vehicle_release_k`` is drone k's release (or the plan's start) on its own clock and
``release_k`` the same on the common clock, relative to mission time 0. Two ways to know it:

- **the common clock** (:func:`releases_on_common_clock`): SYSTEM_TIME pairs each drone's
  boot time with UNIX time, which GPS gives a real vehicle and one ``--start-time`` gives
  the SITL simulators. Every sample then sits on one clock, so being in step is measured
  as it happens: a late release, or a drone that falls behind, shows;
- **the releases in the logs** (:func:`releases_from_logs`), for logs without SYSTEM_TIME:
  each drone's first MISSION_CURRENT naming the released item, on its own clock and as the
  ground station received it (which includes the link's delays).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from flycrane.errors import FlyCraneError
from missions.flight_report.vehicle_log import VehicleLog


@dataclass(frozen=True)
class Releases:
    """Each drone's release on its own clock and on the common one (module docstring)."""

    vehicle_time: NDArray[np.float64]  #: (3,) [s]
    common_time: NDArray[np.float64]  #: (3,) [s], relative to the first release (min 0)
    log_time: float = 0.0  #: mission time 0 on the log's clock [s since the Unix epoch]

    @property
    def spread(self) -> float:
        """Between the first and the last release [s]."""
        return float(np.ptp(self.common_time))

    def mission_time(self, drone: int, vehicle_time: NDArray[np.float64]) -> NDArray[np.float64]:
        return self.common_time[drone] + (vehicle_time - self.vehicle_time[drone])

    def vehicle_time_of(self, drone: int, mission_time: NDArray[np.float64]) -> NDArray[np.float64]:
        return self.vehicle_time[drone] + (mission_time - self.common_time[drone])


class AlignmentError(FlyCraneError, ValueError):
    """The drones' logs cannot be laid on one clock from the plan's start or release."""


def _released(vehicle: VehicleLog, release_seq: int) -> tuple[float, float]:
    event = vehicle.current.first(release_seq)
    if event is None:
        raise AlignmentError(f"{vehicle.name}: no MISSION_CURRENT {release_seq} in the log")
    return event


def releases_from_logs(vehicles: Sequence[VehicleLog], release_seq: int) -> Releases:
    """Releases from the logs alone (module docstring)."""
    events = np.array([_released(v, release_seq) for v in vehicles])
    first = float(events[:, 1].min())
    return Releases(events[:, 0], events[:, 1] - first, first)


def releases_on_common_clock(
    vehicles: Sequence[VehicleLog], release_seq: int | None = None, start: float | None = None
) -> Releases:
    """Every drone on the vehicles' one common clock (their SYSTEM_TIME): mission time 0 at
    common time ``start`` (a stream or onboard execution's plan start), or at the first
    drone's release into ``release_seq`` (missions).

    Raises
    ------
    AlignmentError
        A log without SYSTEM_TIME, or neither a start nor a release to align on.
    """
    offsets = []
    for vehicle in vehicles:
        if vehicle.clock_offset is None:
            raise AlignmentError(f"{vehicle.name}: no SYSTEM_TIME with a UNIX time in the log")
        offsets.append(vehicle.clock_offset)
    offset = np.array(offsets)
    if release_seq is not None:
        vehicle_time = np.array([_released(v, release_seq)[0] for v in vehicles])
        common = vehicle_time + offset
        start = float(common.min())
    elif start is not None:
        vehicle_time = start - offset
        common = np.full(len(vehicles), start)
    else:
        raise AlignmentError("nothing to align the drones on: no start, no release")
    first = vehicles[0].estimated
    log_time = float(np.interp(vehicle_time[0], first.time, first.log_time))
    return Releases(vehicle_time, common - start, log_time)
