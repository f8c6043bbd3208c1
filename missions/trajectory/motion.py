"""Where the drones are told to be, or will be: each drone's position on one time base.

Mission time is zero at the release. :class:`DroneMotion` holds dense samples of the three
drones' positions (the autopilot's target as the mission model flies it, or the modelled
vehicle following it, :mod:`missions.autopilots.chain`) and answers "where is drone j at
time t", also with a clock of its own per drone (a drone that started late or flies slower,
for the timing tolerance). Everything that judges a mission before it is flown (leg checks,
timing tolerance: the targets) and after (the flight report: the vehicles) asks it.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from missions.autopilots.chain import ChainFlight
from missions.trajectory.tracks import samples_at_rate

#: Sampling of a motion [s].
MOTION_STEP_S = 0.01
#: How far ahead of the last match a progress search looks [samples of the plan].
PROGRESS_WINDOW = 250


def forward_progress(
    planned: NDArray[np.float64], flown: NDArray[np.float64], backward: bool = False
) -> NDArray[np.int64]:
    """Index into ``planned`` (M, D) nearest each ``flown`` (N, D) row, searched forward from
    the previous match within :data:`PROGRESS_WINDOW` samples (a path may cross itself, and
    a formation pass the same place twice); with ``backward``, as far back too (a flight
    that may go back along its path)."""
    index = np.zeros(len(flown), dtype=np.int64)
    last = 0
    for n, point in enumerate(flown):
        begin = max(last - PROGRESS_WINDOW, 0) if backward else last
        stop = min(last + PROGRESS_WINDOW, len(planned))
        last = begin + int(np.argmin(np.linalg.norm(planned[begin:stop] - point, axis=-1)))
        index[n] = last
    return index


def formation_progress(
    plan_time: NDArray[np.float64], plan_drones: NDArray[np.float64], drones: NDArray[np.float64]
) -> NDArray[np.float64]:
    """The plan time (M,) whose three drone positions (M, 3, 3) are nearest the three
    drones (N, 3, 3): where the formation is along the plan, whatever delay all three share."""
    index = forward_progress(plan_drones.reshape(len(plan_drones), 9), drones.reshape(-1, 9))
    return np.asarray(plan_time)[index]


@dataclass(frozen=True)
class DroneMotion:
    """Positions of three drones on mission time, and the planned waypoints."""

    time: NDArray[np.float64]  #: (N,) [s]
    drones: NDArray[np.float64]  #: (N, 3, 3) ENU [m]
    waypoint_time: NDArray[np.float64]  #: (K,) planned arrival at each waypoint [s]

    @property
    def duration(self) -> float:
        return float(self.time[-1])

    def at(self, t: NDArray[np.float64]) -> NDArray[np.float64]:
        """Positions at mission times ``t`` (held at the ends), (len(t), 3, 3)."""
        t = np.asarray(t, dtype=float)
        return self.at_each(np.repeat(t[:, None], 3, axis=1))

    def at_each(self, local: NDArray[np.float64]) -> NDArray[np.float64]:
        """Drone j at its own time ``local[:, j]`` (C, 3) -> (C, 3, 3)."""
        columns = [
            np.column_stack(
                [np.interp(local[:, j], self.time, self.drones[:, j, i]) for i in range(3)]
            )
            for j in range(3)
        ]
        return np.stack(columns, axis=1)

    @classmethod
    def straight(
        cls, waypoint_time: NDArray[np.float64], waypoint_drones: NDArray[np.float64]
    ) -> DroneMotion:
        """Straight legs at constant speed between timed waypoints (K, 3, 3)."""
        return cls(np.asarray(waypoint_time, float), np.asarray(waypoint_drones, float),
                   np.asarray(waypoint_time, float))  # fmt: skip

    @classmethod
    def from_chains(
        cls,
        flights: Sequence[ChainFlight],
        waypoint_time: NDArray[np.float64],
        vehicles: bool = False,
    ) -> DroneMotion:
        """Three drones' modelled chains, resampled every :data:`MOTION_STEP_S` until the
        last arrival: their targets (what the autopilots are told), or with ``vehicles``
        where the modelled vehicles following them will be."""
        end = max(float(f.time[-1]) for f in flights)
        t = np.arange(0.0, end + MOTION_STEP_S / 2, MOTION_STEP_S)
        at = [f.vehicle_at if vehicles else f.at for f in flights]
        return cls(t, np.stack([f(t) for f in at], axis=1), np.asarray(waypoint_time))

    def decimated(self, rate: float) -> DroneMotion:
        """The samples that show the motion at ``rate`` Hz (the last one kept): what a
        reader that interpolates needs (:data:`missions.task.documents.STORED_MOTION_RATE_HZ`)."""
        keep = samples_at_rate(self.time, rate)
        return DroneMotion(self.time[keep], self.drones[keep], self.waypoint_time)

    def as_dict(self) -> dict[str, list]:
        return {
            "time": self.time.tolist(),
            "drones_enu": self.drones.tolist(),
            "waypoint_time": self.waypoint_time.tolist(),
        }

    @classmethod
    def from_dict(cls, data: dict) -> DroneMotion:
        return cls(
            np.array(data["time"]), np.array(data["drones_enu"]), np.array(data["waypoint_time"])
        )
