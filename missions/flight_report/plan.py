"""What the drones were told to do, on mission time (zero at the release), read from a
task's directory as ``flycrane plan`` wrote it: the autopilots' modelled motion
(:class:`~missions.motion.DroneMotion`) and the dense plan of configurations on the same
time."""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from flycrane.kinematics import drone_positions_from_configuration
from missions.motion import DroneMotion
from missions.task import ResolvedTask, TaskSpec, resolve_task
from missions.tracks import Track
from missions.waypoints import planned_configurations

#: Plan time between the samples progress is matched against [s].
PROGRESS_STEP_S = 0.02


@dataclass(frozen=True)
class PlannedFlight:
    """The timed waypoints (straight legs between them) and the dense planned track."""

    resolved: ResolvedTask
    waypoint_time: NDArray[np.float64]  #: (K,) [s]
    waypoint_drones: NDArray[np.float64]  #: (K, 3, 3) ENU [m]
    track: Track  #: the dense plan: configurations and drone positions on mission time
    motion: DroneMotion  #: where the autopilots are told to be
    timing_tolerance: dict[str, float | str]

    @property
    def duration(self) -> float:
        return float(self.waypoint_time[-1])

    def drones_at(self, t: NDArray[np.float64]) -> NDArray[np.float64]:
        """Commanded drone positions at mission times ``t`` (len(t), 3, 3)."""
        return self.motion.at(t)

    def configurations_at(self, t: NDArray[np.float64]) -> NDArray[np.float64]:
        """Planned configurations at mission times ``t`` (len(t), 9)."""
        return planned_configurations(self.track, np.clip(t, 0.0, self.track.duration))

    def progress_samples(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Plan times and commanded drone positions every :data:`PROGRESS_STEP_S`."""
        t = np.arange(0.0, self.duration + PROGRESS_STEP_S / 2, PROGRESS_STEP_S)
        return t, self.drones_at(t)

    @classmethod
    def read(cls, task_dir: Path) -> PlannedFlight:
        """From ``task.json`` and ``tracks.json`` of a task's directory."""
        task = TaskSpec.model_validate_json((task_dir / "task.json").read_text(encoding="utf-8"))
        resolved = resolve_task(task)
        tracks = json.loads((task_dir / "tracks.json").read_text(encoding="utf-8"))
        q = np.array(tracks["dense"]["configurations"])
        system = resolved.problem.system
        track = Track(
            np.array(tracks["dense"]["time"]), q, drone_positions_from_configuration(system, q)
        )
        return cls(
            resolved=resolved,
            waypoint_time=np.array(tracks["time"]),
            waypoint_drones=np.array(tracks["drones_enu"]),
            track=track,
            motion=DroneMotion.from_dict(tracks["motion"]),
            timing_tolerance=tracks["timing_tolerance"],
        )
