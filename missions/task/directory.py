"""A task's directory: the one owner of its file names and of what each file holds.

``flycrane plan`` and the service's workers write it (:mod:`missions.task.pipeline`); the
SITL harness, the flight report, the viewer and the service read it back, all through
:class:`TaskDirectory`, as typed models (:mod:`missions.task.documents`: ``TaskOutcome`` for
``summary.json``, ``Tracks`` for ``tracks.json``; the missions and their parameters).
No consumer reads a file by name or a JSON document by key.

=====================  =====================================================================
file                   holds
=====================  =====================================================================
task.json              the task written out whole (system, scene, start, goal, planner)
path.json              the smoothed path and the planner's raw one (configurations)
tracks.json            waypoints, dense plan, speed limits, annotations, modelled motion
drone{k}.waypoints     drone k's mission, QGC WPL 110; ``.plan`` QGroundControl; ``.mission
                       .json`` lossless; ``.parm`` the parameters its timing assumes;
                       ``.trajectory.csv`` its time law (:mod:`missions.export.
                       trajectory_file`)
mission.mcap           the mission for Foxglove; profile.png the tensions and thrusts
mesh{k}.{suffix}       the scene's mesh files, copied in: task.json names them so
summary.json           :class:`TaskOutcome`: status, planner statistics, metrics, mission
=====================  =====================================================================

A run writes into ``.partial/`` inside the directory, and its summary, written last, moves
the files in: an interrupted run leaves the last finished run whole, never one run's
missions beside another's task.
"""

from __future__ import annotations

import json
import os
import re
import shutil
from collections.abc import Iterable
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from flycrane.errors import FlyCraneError, InputError
from flycrane.world.scene import Mesh, SceneSpec, Shape
from missions.export.formats import dumps, mission_from_json
from missions.export.items import DroneMission
from missions.export.parameter_file import parse_parameter_file
from missions.export.trajectory_file import read_trajectory_text
from missions.geodesy import enu_from_geodetic, enu_from_ned
from missions.task.documents import DRONES, MissionSummary, TaskOutcome, Tracks
from missions.task.spec import TaskSpec
from missions.trajectory.drone_trajectory import DroneTrajectory

TASK_FILE = "task.json"
PATH_FILE = "path.json"
TRACKS_FILE = "tracks.json"
SUMMARY_FILE = "summary.json"
#: Where a run writes its files until its summary moves them in (module docstring).
STAGING_DIR = ".partial"
#: The summary's name until it is moved into place, the run's last step.
STAGED_SUMMARY = ".summary.json"
MCAP_FILE = "mission.mcap"
#: The task's mesh files, copied in (:meth:`TaskDirectory.write_task`): mesh1.stl, ...
MESH_STEM = "mesh"
MESH_FILE = re.compile(rf"{MESH_STEM}[0-9]+(\.[a-z0-9]+)?")
PROFILE_FILE = "profile.png"
#: The files of each drone's mission, in the order they are written.
MISSION_SUFFIXES = ("waypoints", "plan", "mission.json", "parm", "trajectory.csv")


def mission_file(drone: int, suffix: str) -> str:
    """``drone{k}.{suffix}``: one of :data:`MISSION_SUFFIXES` of drone ``k`` (1-based)."""
    return f"drone{drone}.{suffix}"


#: Every file a task's run writes (the table above).
OWN_FILES = (
    TASK_FILE, PATH_FILE, TRACKS_FILE, SUMMARY_FILE, MCAP_FILE, PROFILE_FILE,
    *(mission_file(k, suffix) for k in DRONES for suffix in MISSION_SUFFIXES),
)  # fmt: skip


class TaskDirectoryError(FlyCraneError):
    """A file of a task's directory is missing or unreadable; ``name`` says which."""

    def __init__(self, directory: Path, name: str, reason: str) -> None:
        self.directory, self.name, self.reason = directory, name, reason
        super().__init__(f"{directory.name}: {name} {reason}")


class TaskDirectory:
    """A task's directory: writes its files (recording each as an artifact) and reads them
    back as typed models.

    Raises (every reader)
    ---------------------
    TaskDirectoryError
        A file is missing or does not hold what this version writes.
    """

    def __init__(self, path: str | Path) -> None:
        self.path = Path(path)
        #: what has been written, name -> file (relative), in the order written
        self.artifacts: dict[str, str] = {}
        self._staging: Path | None = None

    def create(self) -> TaskDirectory:
        """Make the directory and an empty staging folder in it for a run to write into
        (an interrupted run's is cleared)."""
        self.path.mkdir(parents=True, exist_ok=True)
        self._staging = self.path / STAGING_DIR
        shutil.rmtree(self._staging, ignore_errors=True)
        self._staging.mkdir()
        return self

    def file(self, name: str) -> Path:
        """Where the file ``name`` is written: in the staging folder while a run writes."""
        return (self._staging or self.path) / name

    # writing ---------------------------------------------------------------------------

    def write_text(self, name: str, text: str, artifact: str | None = None) -> None:
        """Write ``name`` and record it as the artifact ``artifact`` (default: its name). A
        write that fails says which file (a full disk fails the write, not the open, and
        its error names none)."""
        path = self.file(name)
        try:
            path.write_text(text, encoding="utf-8")
        except OSError as error:
            raise OSError(error.errno, error.strerror, str(path)) from error
        self.record(name, artifact)

    def record(self, name: str, artifact: str | None = None) -> None:
        """Record a file written by someone else (an MCAP log, a plot) as an artifact."""
        self.artifacts[artifact or name] = name

    def write_task(self, task: TaskSpec, base_dir: Path | None = None) -> None:
        """task.json, the task written out whole: the mesh files its scene names (relative
        to ``base_dir``) are copied in as ``mesh{k}.{suffix}`` and named so, so that the
        directory is planned again, judged and viewed wherever it is (its readers take
        the directory as the task's base)."""
        scene = task.scene
        if isinstance(scene, SceneSpec):
            copied = 0

            def own(shape: Shape) -> Shape:
                nonlocal copied
                if not isinstance(shape, Mesh) or shape.file is None:
                    return shape
                source = Path(shape.file) if base_dir is None else base_dir / shape.file
                copied += 1
                name = f"{MESH_STEM}{copied}{source.suffix.lower()}"
                try:
                    shutil.copyfile(source, self.file(name))
                except OSError as error:
                    raise OSError(error.errno, error.strerror, str(source)) from error
                self.record(name)
                return shape.model_copy(update={"file": name})

            payload = scene.payload.model_copy(
                update={"shapes": tuple(own(s) for s in scene.payload.shapes)}
            )
            scene = scene.model_copy(
                update={"obstacles": tuple(own(s) for s in scene.obstacles), "payload": payload}
            )
        written = task.model_copy(update={"scene": scene})
        self.write_text(TASK_FILE, dumps(written.model_dump(mode="json")))

    def write_path(self, configurations: NDArray[np.float64], raw: NDArray[np.float64]) -> None:
        document = {"configurations": configurations.tolist(), "raw_path": raw.tolist()}
        self.write_text(PATH_FILE, dumps(document))

    def write_tracks(self, tracks: Tracks) -> None:
        self.write_text(TRACKS_FILE, dumps(tracks.as_dict()))

    def write_summary(self, outcome: TaskOutcome) -> TaskOutcome:
        """Write summary.json, the run's last file, and move the run's files in; the
        outcome returned lists it among the artifacts. The earlier summary goes first (the
        directory reads as not done while its files change), and so do the files an earlier
        run wrote here and this one did not: beside a failed run's summary, an earlier
        run's missions would be taken for its own and could be flown. Other files are not
        the task's and are left alone."""
        staging = self._staging or self.path
        self.record(SUMMARY_FILE)
        (staging / STAGED_SUMMARY).write_text(dumps(outcome.as_dict()), encoding="utf-8")
        (self.path / SUMMARY_FILE).unlink(missing_ok=True)
        written = [name for name in self.artifacts.values() if name != SUMMARY_FILE]
        meshes = {p.name for p in self.path.glob(f"{MESH_STEM}*") if MESH_FILE.fullmatch(p.name)}
        for name in (set(OWN_FILES) | meshes) - set(written):
            (self.path / name).unlink(missing_ok=True)
        for name in written if staging != self.path else ():
            os.replace(staging / name, self.path / name)
        os.replace(staging / STAGED_SUMMARY, self.path / SUMMARY_FILE)
        if staging != self.path:
            staging.rmdir()
            self._staging = None
        return TaskOutcome(**{**outcome.__dict__, "artifacts": dict(self.artifacts)})

    # reading ---------------------------------------------------------------------------

    def read_text(self, name: str) -> str:
        try:
            return (self.path / name).read_text(encoding="utf-8")
        except FileNotFoundError:
            raise TaskDirectoryError(self.path, name, "is missing") from None
        except (OSError, UnicodeDecodeError) as error:
            raise TaskDirectoryError(self.path, name, f"is unreadable: {error}") from None

    def _document(self, name: str) -> dict[str, Any]:
        try:
            document = json.loads(self.read_text(name))
        except ValueError as error:
            raise TaskDirectoryError(self.path, name, f"is not JSON: {error}") from None
        if not isinstance(document, dict):
            raise TaskDirectoryError(self.path, name, "is not a JSON object")
        return document

    def _model(self, name: str, parse: Any) -> Any:
        document = self._document(name)
        try:
            return parse(document)
        except (KeyError, TypeError, ValueError) as error:
            raise TaskDirectoryError(
                self.path, name, f"does not hold what this version writes ({error!r})"
            ) from None

    def task(self) -> TaskSpec:
        """The task as planned, written out whole (system, scene, start, goal, planner); the
        mesh files its scene names must be in the directory (:meth:`write_task`)."""
        task: TaskSpec = self._model(TASK_FILE, TaskSpec.model_validate)
        if isinstance(task.scene, SceneSpec):
            for shape in (*task.scene.obstacles, *task.scene.payload.shapes):
                if isinstance(shape, Mesh) and shape.file is not None:
                    if not (self.path / shape.file).is_file():
                        reason = f"is missing (task.json's mesh {shape.name or shape.file!r})"
                        raise TaskDirectoryError(self.path, shape.file, reason)
        return task

    def planned_path(self) -> NDArray[np.float64]:
        """The smoothed path the missions follow, (M, 9)."""
        return self._model(PATH_FILE, lambda d: np.array(d["configurations"], dtype=float))

    def tracks(self) -> Tracks:
        return self._model(TRACKS_FILE, Tracks.from_dict)

    def summary(self) -> TaskOutcome:
        return self._model(SUMMARY_FILE, TaskOutcome.from_dict)

    def mission_summary(self) -> MissionSummary:
        """summary.json's mission (only a task that was planned to the end has one)."""
        mission = self.summary().mission
        if mission is None:
            raise TaskDirectoryError(self.path, SUMMARY_FILE, "has no mission (task not done)")
        return mission

    def missions(self, drones: Iterable[int] = DRONES) -> list[DroneMission]:
        """Each drone's mission (``drone{k}.mission.json``)."""
        return [self._model(mission_file(k, "mission.json"), mission_from_json) for k in drones]

    def trajectory(self) -> DroneTrajectory:
        """The three drones' trajectories (``drone{k}.trajectory.csv``), in the task's frame
        (its origin from task.json)."""
        origin = self.task().mission.origin
        rows, homes = [], []
        for k in DRONES:
            name = mission_file(k, "trajectory.csv")
            try:
                time, data, home, set_down = read_trajectory_text(self.read_text(name), name)
            except InputError as error:
                raise TaskDirectoryError(self.path, name, str(error)) from None
            rows.append(data)
            homes.append(home)
        if any(len(r) != len(time) for r in rows):
            raise TaskDirectoryError(self.path, "drone*.trajectory.csv", "differ in length")
        enu = np.stack([enu_from_ned(r.reshape(-1, 3, 3)) for r in rows], axis=1)
        lat, lon, alt = np.array(homes).T
        return DroneTrajectory(
            time,
            enu[:, :, 0],
            enu[:, :, 1],
            enu[:, :, 2],
            enu_from_geodetic(lat, lon, alt, origin),
            set_down,
        )

    def parameters(self, drones: Iterable[int] = DRONES) -> list[dict[str, float]]:
        """The parameters each drone's mission assumes (``drone{k}.parm``)."""
        parameters = []
        for k in drones:
            name = mission_file(k, "parm")
            try:
                parameters.append(parse_parameter_file(self.read_text(name), name))
            except ValueError as error:
                reason = f"is not a parameter file: {error}"
                raise TaskDirectoryError(self.path, name, reason) from None
        return parameters
