"""One time base for three drones whose clocks are their own.

Each drone's log is timed by its own clock (``time_boot_ms``): right for its own motion,
but the three clocks start at different instants (and three simulators may even run at
slightly different paces). The drones are coupled by the load in real time, so the flight
is judged on *mission time*: zero at the first drone's release, each drone's samples
placed by

    mission_time = release_k + (vehicle_time - vehicle_release_k)

where ``vehicle_release_k`` is drone k's release on its own clock and ``release_k`` its
release on the common clock, relative to the first. From the release on, each drone's own
clock measures its flight (no drift between simulators, no network delay in the samples).

A drone's release on its own clock is the first MISSION_CURRENT naming the released item
(to half a stream period, :mod:`.vehicle_log`). On the common clock it is

- **the ground's send** of its MISSION_SET_CURRENT (our SITL harness knows it): on loopback
  a message reaches the vehicle within microseconds, and a simulator handles it at its next
  loop (0.25 ms of wall time at x10);
- **its receipt**, from the logs alone (any flight recorded by one ground station): the log
  record of that MISSION_CURRENT. This includes the link's delays, which on a busy ground
  station can reach tens of milliseconds.

The receipt times are not precise enough to map a drone's clock onto the ground's (a
simulated second lasts a tenth of a wall second, in which a busy reader thread drifts by
tens of milliseconds), which is why each drone's own clock is used from its release on.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

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


class AlignmentError(ValueError):
    """A drone's log does not show its release."""


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


def releases_from_sends(
    vehicles: Sequence[VehicleLog], release_seq: int, sent_log_time: Sequence[float]
) -> Releases:
    """Releases with the ground's send times on the log clock (module docstring)."""
    vehicle_time = [_released(v, release_seq)[0] for v in vehicles]
    sent = np.asarray(sent_log_time, dtype=float)
    return Releases(np.array(vehicle_time), sent - sent.min(), float(sent.min()))
