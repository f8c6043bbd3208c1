"""Dense drone tracks of a planned path on the one time law the three drones share.

The path (configurations joined by the planner's local path) is resampled densely; forward
kinematics gives the drones' positions and the platform's orientation at every sample, and
:func:`~missions.trajectory.time_law.time_law` the times.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from flycrane.model.cable_system import CableSystem
from flycrane.model.kinematics import drone_positions_from_configuration, forward_kinematics
from flycrane.planning.state_space import ConfigurationSpace
from missions.options import MissionOptions
from missions.trajectory.time_law import time_law

#: Dense resampling step of the path [state-space distance, ~m of drone travel].
TRACK_RESOLUTION = 0.02


@dataclass(frozen=True)
class Track:
    """A dense timed track: configurations, drone positions (ENU) and times."""

    time: NDArray[np.float64]  #: (K,) seconds from the first configuration
    q: NDArray[np.float64]  #: (K, 9)
    drones: NDArray[np.float64]  #: (K, 3, 3) drone positions [m]

    @property
    def duration(self) -> float:
        return float(self.time[-1])

    def index_at(self, t: NDArray[np.float64]) -> tuple[NDArray[np.int64], NDArray[np.float64]]:
        """Segment index and fraction within it for times t (clamped to the track)."""
        t = np.clip(np.asarray(t, dtype=float), 0.0, self.duration)
        k = np.clip(np.searchsorted(self.time, t, side="right") - 1, 0, len(self.time) - 2)
        span = self.time[k + 1] - self.time[k]
        return k, np.divide(t - self.time[k], span, out=np.zeros_like(t), where=span > 0)


def samples_at_rate(time: NDArray[np.float64], rate: float) -> NDArray[np.int64]:
    """Indices of the samples of increasing times (K,) that show a track at ``rate`` Hz:
    the first sample at or after each multiple of 1 / rate (to a microsecond: times summed
    in steps are not exact), and the last one."""
    time = np.asarray(time, dtype=float)
    ticks = np.arange(0.0, time[-1] - time[0], 1.0 / rate) + time[0]
    return np.union1d(np.searchsorted(time, ticks - 1e-6), [len(time) - 1])


def least_duration(system: CableSystem, q: NDArray[np.float64], options: MissionOptions) -> float:
    """A lower bound [s] on the time the drones take through configurations (K, 9) in
    turn: the longest drone's straight-line travel at ``max_drone_speed`` (its track
    between them is no shorter, its speed no higher)."""
    drones = drone_positions_from_configuration(system, q)
    travel = np.linalg.norm(np.diff(drones, axis=0), axis=-1).sum(axis=0)
    return float(travel.max(initial=0.0)) / options.max_drone_speed


def track_from_path(
    system: CableSystem,
    space: ConfigurationSpace,
    path: NDArray[np.float64],
    options: MissionOptions,
    resolution: float = TRACK_RESOLUTION,
) -> Track:
    """Dense track of a planned path with its shared time law."""
    poses = forward_kinematics(system, space.discretize_path(path, resolution))
    step = np.linalg.norm(np.diff(poses.drones, axis=0), axis=-1).max(1)
    poses = poses.rows(np.concatenate([[True], step > 0]))
    if len(poses.q) < 2:
        return Track(np.zeros(1), poses.q, poses.drones)
    return Track(time_law(poses.drones, poses.rotation, options), poses.q, poses.drones)
