"""What the drones were told to do, on mission time (zero at the release), read from a
task's directory as ``flycrane plan`` wrote it: the autopilots' modelled motion
(:class:`~missions.trajectory.motion.DroneMotion`) and the dense plan of configurations on the same
time."""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from flycrane.model.kinematics import drone_positions_from_configuration
from flycrane.planning.validity import ValidityChecker
from missions.task.spec import ResolvedTask, TaskSpec, resolve_task
from missions.trajectory.motion import DroneMotion
from missions.trajectory.tracks import Track
from missions.trajectory.waypoints import planned_configurations

#: Plan time between the samples progress is matched against [s].
PROGRESS_STEP_S = 0.02


def _end_seqs(task_dir: Path) -> tuple[int, int, int]:
    """Each drone's last mission item (``drone{k}.mission.json``)."""
    seqs = []
    for k in (1, 2, 3):
        mission = json.loads((task_dir / f"drone{k}.mission.json").read_text(encoding="utf-8"))
        seqs.append(int(mission["items"][-1]["seq"]))
    return (seqs[0], seqs[1], seqs[2])


@dataclass(frozen=True)
class ContactWindow:
    """A set-down: between these mission times, touching these surfaces is the leg's
    intended end (:mod:`missions.trajectory.vertical_legs`); the window stays open to the end of the
    flight (``end`` inf), because the load stays on them through the final hold."""

    start: float
    end: float
    surfaces: tuple[str, ...]


@dataclass(frozen=True)
class PlannedFlight:
    """The timed waypoints, the dense planned track and the modelled vehicles' motion."""

    resolved: ResolvedTask
    waypoint_time: NDArray[np.float64]  #: (K,) [s]
    waypoint_drones: NDArray[np.float64]  #: (K, 3, 3) ENU [m]
    track: Track  #: the dense plan: configurations and drone positions on mission time
    #: where the model says the vehicles will be (tracks.json's vehicle_motion): each
    #: drone's progress and its error in time are measured against it, so a drone that lags
    #: its target as the model predicts (vertical legs lag less) is not out of step
    motion: DroneMotion
    timing_tolerance: dict[str, float | str]
    end_seq: tuple[int, int, int]  #: each drone's last item: the hold after the last leg
    contact_windows: tuple[ContactWindow, ...] = ()

    @property
    def duration(self) -> float:
        """Release to the end of the last leg (a set-down, if any) [s]."""
        return self.motion.duration

    def real_validity(self, surfaces: tuple[str, ...] = ()) -> ValidityChecker:
        """The task's validity on the real obstacles (no planning clearance), without the
        named ``surfaces``."""
        return self.resolved.problem.validity.with_clearance(0.0).without(surfaces)

    def drones_at(self, t: NDArray[np.float64]) -> NDArray[np.float64]:
        """Modelled drone positions at mission times ``t`` (len(t), 3, 3)."""
        return self.motion.at(t)

    def configurations_at(self, t: NDArray[np.float64]) -> NDArray[np.float64]:
        """Planned configurations at mission times ``t`` (len(t), 9)."""
        return planned_configurations(self.track, np.clip(t, 0.0, self.track.duration))

    def progress_samples(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Plan times and modelled drone positions every :data:`PROGRESS_STEP_S`."""
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
            motion=DroneMotion.from_dict(tracks.get("vehicle_motion", tracks["motion"])),
            timing_tolerance=tracks["timing_tolerance"],
            end_seq=_end_seqs(task_dir),
            contact_windows=tuple(
                ContactWindow(leg["start_time"], math.inf, tuple(leg["surfaces"]))
                for leg in [tracks.get("set_down")]
                if leg is not None
            ),
        )
