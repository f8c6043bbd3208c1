"""What the drones were told to do, on mission time (zero at the release), read from a
task's directory (:class:`~missions.task.directory.TaskDirectory`): the autopilots'
modelled motion (:class:`~missions.trajectory.motion.DroneMotion`) and the dense plan of
configurations on the same time."""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from flycrane.model.kinematics import drone_positions_from_configuration
from flycrane.planning.problem import PlanningProblem
from flycrane.planning.validity import ValidityChecker
from flycrane.world.scene import SceneSpec
from missions.execution.group_clock import GroupClock
from missions.task.directory import TaskDirectory
from missions.task.documents import Release
from missions.task.spec import TaskSpec
from missions.trajectory.drone_trajectory import DroneTrajectory
from missions.trajectory.motion import MOTION_STEP_S, DroneMotion, forward_progress
from missions.trajectory.tracks import Track
from missions.trajectory.waypoints import planned_configurations

#: Plan time between the samples progress is matched against [s].
PROGRESS_STEP_S = 0.02


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

    task: TaskSpec  #: as planned, written out whole
    problem: PlanningProblem  #: of the task's system and scene, as planned
    real: ValidityChecker  #: the problem's validity on the real obstacles (no clearance)
    waypoint_time: NDArray[np.float64]  #: (K,) [s]
    waypoint_drones: NDArray[np.float64]  #: (K, 3, 3) ENU [m]
    track: Track  #: the dense plan: configurations and drone positions on mission time
    #: where the model says the vehicles will be (tracks.json's vehicle_motion): each
    #: drone's progress and its error in time are measured against it, so a drone that lags
    #: its target as the model predicts (vertical legs lag less) is not out of step
    motion: DroneMotion
    timing_tolerance: dict[str, float | str]
    release: Release
    end_seq: tuple[int, int, int]  #: each drone's last item: the hold after the last leg
    contact_windows: tuple[ContactWindow, ...] = ()
    #: the executor that flew it (:mod:`missions.execution`); for ``stream`` and ``onboard``
    #: :attr:`motion` is the trajectory as the group clock played it (:meth:`executed`)
    mode: str = "missions"
    nominal_duration: float | None = None  #: the plan's own, at full rate [s]

    @property
    def reversible(self) -> bool:
        """Whether the flight may go back along its path (an executor's retreat)."""
        return self.mode != "missions"

    @property
    def duration(self) -> float:
        """Release to the end of the last leg (a set-down, if any) [s]."""
        return self.motion.duration

    def executed(
        self, trajectory: DroneTrajectory, clock: GroupClock, mode: str, end: float
    ) -> PlannedFlight:
        """The plan as an execution played it: ``trajectory`` at the group ``clock``'s plan
        time, on mission time from the clock's start to ``end`` [s]; the dense plan's
        configurations follow the drones (nearest dense sample, searched forward)."""
        t = np.arange(0.0, end + MOTION_STEP_S / 2, MOTION_STEP_S)
        tau = np.array([clock.tau(clock.start + x) for x in t])
        drones = trajectory.in_task_frame(trajectory.at(tau)[0])
        index = forward_progress(
            self.track.drones.reshape(-1, 9), drones.reshape(-1, 9), backward=True
        )
        windows = self.contact_windows
        if trajectory.set_down_start is not None and (tau >= trajectory.set_down_start).any():
            start = float(t[np.argmax(tau >= trajectory.set_down_start)])
            windows = tuple(replace(w, start=start) for w in windows)
        return replace(
            self,
            track=Track(t, self.track.q[index], drones),
            motion=DroneMotion(t, drones, np.array([0.0, float(t[-1])])),
            mode=mode,
            nominal_duration=trajectory.duration,
            contact_windows=windows,
        )

    def real_validity(self, surfaces: tuple[str, ...] = ()) -> ValidityChecker:
        """The task's validity on the real obstacles (no planning clearance), without the
        named ``surfaces``."""
        return self.real.without(surfaces)

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
        """From a task's directory.

        Raises
        ------
        TaskDirectoryError
            A file the report needs is missing or unreadable.
        """
        directory = TaskDirectory(task_dir)
        task = directory.task()
        assert isinstance(task.scene, SceneSpec)  # written out whole (task.json)
        problem = PlanningProblem.from_scene(
            task.scene, None if isinstance(task.system, str) else task.system, Path(task_dir)
        )
        tracks = directory.tracks()
        q = tracks.dense_configurations
        track = Track(tracks.dense_time, q, drone_positions_from_configuration(problem.system, q))
        end = [m.items[-1].seq for m in directory.missions()]
        return cls(
            task=task,
            problem=problem,
            real=problem.validity.with_clearance(0.0),
            waypoint_time=tracks.time,
            waypoint_drones=tracks.drones_enu,
            track=track,
            motion=tracks.vehicle_motion,
            timing_tolerance=tracks.timing_tolerance.as_dict(),
            release=directory.mission_summary().release,
            end_seq=(end[0], end[1], end[2]),
            contact_windows=tuple(
                ContactWindow(leg.start, math.inf, leg.leg.surfaces)
                for leg in [tracks.set_down]
                if leg is not None
            ),
        )
