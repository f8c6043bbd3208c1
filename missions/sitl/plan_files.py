"""What a SITL flight reads from a task's directory (``flycrane plan`` output): each
drone's mission and parameters, the release and the plan's time law, the position-error
model the plan assumed and, for the stream mode, where a faulty drone's followers may go."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Literal

from missions.execution.anchor import FormationRoom
from missions.export.items import DroneMission
from missions.export.onboard import onboard_mission
from missions.options import GeodeticOrigin
from missions.position_error import PositionErrorModel, position_error_model
from missions.task.directory import TaskDirectory
from missions.trajectory.drone_trajectory import DroneTrajectory

Mode = Literal["missions", "stream", "onboard"]


@dataclass(frozen=True)
class FlightPlanFiles:
    """What a flight needs from a task's directory (``flycrane plan`` output)."""

    missions: tuple[DroneMission, ...]
    parameters: tuple[dict[str, float], ...]  #: per drone, from ``drone{k}.parm``
    hold_seq: int  #: the NAV_LOITER_UNLIM at the start
    release_seq: int  #: the item the release jumps to
    end_seq: tuple[int, ...]  #: per drone, its last item (the hold at the end)
    duration_s: float  #: the missions' duration after the release
    trajectory: DroneTrajectory
    model: PositionErrorModel
    origin: GeodeticOrigin
    home_height: float
    room: FormationRoom | None  #: where a faulty drone's followers may go (stream only)

    @classmethod
    def read(cls, task_dir: Path, mode: Mode = "stream") -> FlightPlanFiles:
        """For a flight in ``mode``, from a task's directory (:class:`TaskDirectory`).

        Raises
        ------
        TaskDirectoryError
            A file the flight needs is missing or unreadable.
        """
        directory = TaskDirectory(task_dir)
        missions, summary = directory.missions(), directory.mission_summary()
        options = (task := directory.task()).mission
        model, trajectory = position_error_model(options.position_error), directory.trajectory()
        room = None  # built before the flight: its first check loads the compiled checker
        if mode == "stream":
            room = FormationRoom.of_task(task, task_dir, trajectory, model.obstacle_clearance)
        return cls(
            missions=tuple(missions),
            parameters=tuple(directory.parameters()),
            hold_seq=summary.release.hold_seq,
            release_seq=summary.release.release_seq,
            end_seq=tuple(m.items[-1].seq for m in missions),
            duration_s=summary.duration,
            trajectory=trajectory,
            model=model,
            origin=options.origin,
            home_height=options.home_height,
            room=room,
        )

    def flown_duration(self, mode: Mode) -> float:
        """The plan's duration after the release as ``mode`` flies it [s]: the missions',
        or the trajectory's that the clocked modes play."""
        return self.duration_s if mode == "missions" else self.trajectory.duration

    def for_mode(self, mode: Mode) -> tuple[tuple[DroneMission, ...], int]:
        """The missions to upload for ``mode``, and the item the executor starts."""
        if mode == "onboard":
            return tuple(onboard_mission(m, self.hold_seq) for m in self.missions), (
                self.hold_seq + 1
            )
        return self.missions, self.release_seq
