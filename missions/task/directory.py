"""A task's directory: the one owner of its file names and of what each file holds.

``flycrane plan`` and the service's workers write it (:mod:`missions.task.pipeline`); the
SITL harness, the flight report, the viewer and the service read it back, all through
:class:`TaskDirectory`, as typed models (:class:`TaskOutcome` for ``summary.json``,
:class:`Tracks` for ``tracks.json``, :class:`Release`, the missions and their parameters).
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
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any, Literal

import numpy as np
from numpy.typing import NDArray

from flycrane.errors import FlyCraneError, InputError
from flycrane.planning.metrics import PathMetrics
from flycrane.world.scene import Mesh, SceneSpec, Shape
from missions.autopilots.spline import SpeedLimits
from missions.export.formats import dumps, mission_from_json
from missions.export.items import DroneMission
from missions.export.parameter_file import parse_parameter_file
from missions.export.trajectory_file import read_trajectory_text
from missions.geodesy import enu_from_geodetic, enu_from_ned
from missions.position_error import PositionErrorModel
from missions.task.spec import TaskSpec
from missions.trajectory.drone_trajectory import DroneTrajectory
from missions.trajectory.flight_plan import SetDown
from missions.trajectory.motion import DroneMotion
from missions.trajectory.timing_tolerance import TimingTolerance
from missions.trajectory.vertical_legs import VerticalLeg

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
DRONES = (1, 2, 3)
#: The files of each drone's mission, in the order they are written.
MISSION_SUFFIXES = ("waypoints", "plan", "mission.json", "parm", "trajectory.csv")
#: The rate the modelled motions are stored at in tracks.json [Hz]: read by interpolation,
#: they stay within about a millimetre of the mission model's 100 Hz samples
#: (BENCHMARKS.md "Bounded work"), at a fifth of the size.
STORED_MOTION_RATE_HZ = 20.0

Status = Literal["done", "failed", "cancelled"]


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


@dataclass(frozen=True)
class Release:
    """Where each drone holds before the release (NAV_LOITER_UNLIM) and the item the
    release jumps to (:mod:`missions.export.builder`)."""

    hold_seq: int
    release_seq: int


@dataclass(frozen=True)
class MissionSummary:
    """What the missions of a task are: summary.json's ``mission``."""

    waypoints: int
    duration: float  #: release to the end of the last leg [s]
    max_platform_deviation: float  #: [m] along the modelled targets
    max_cable_length_error: float  #: [m]
    max_tracking_deviation: float  #: [m] along the modelled vehicles
    timing_tolerance: TimingTolerance
    early_legs: tuple[tuple[int, int], ...]  #: (drone, leg), 1-based
    items_per_drone: tuple[int, ...]
    release: Release
    obstacle_clearance: float  #: [m] kept by the plan
    position_error: PositionErrorModel
    lift_off: VerticalLeg | None
    set_down: SetDown | None
    #: [N] the path's least statics margin less what the drones' own errors can take of
    #: it (:mod:`flycrane.model.robust_statics`), and which margin that is (None in a
    #: summary written before they were measured)
    robust_statics_margin: float | None = None
    robust_statics_limit: str | None = None
    #: [m] the path's least gap less what the drones' errors can close there, where the
    #: task asked for it (``mission.robust_clearance``)
    robust_margin: float | None = None

    def as_dict(self) -> dict[str, Any]:
        robust = {
            name: value
            for name, value in (
                ("robust_statics_margin", self.robust_statics_margin),
                ("robust_statics_limit", self.robust_statics_limit),
                ("robust_margin", self.robust_margin),
            )
            if value is not None
        }
        return {
            "waypoints": self.waypoints,
            "duration": self.duration,
            "max_platform_deviation": self.max_platform_deviation,
            "max_cable_length_error": self.max_cable_length_error,
            "max_tracking_deviation": self.max_tracking_deviation,
            "timing_tolerance": self.timing_tolerance.as_dict(),
            "early_legs": [list(e) for e in self.early_legs],
            "items_per_drone": list(self.items_per_drone),
            "release": asdict(self.release),
            "obstacle_clearance": self.obstacle_clearance,
            "position_error": self.position_error.model_dump(),
            "lift_off": self.lift_off.as_dict() if self.lift_off else None,
            "set_down": self.set_down.as_dict() if self.set_down else None,
            **robust,
        }

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> MissionSummary:
        return cls(
            waypoints=int(data["waypoints"]),
            duration=float(data["duration"]),
            max_platform_deviation=float(data["max_platform_deviation"]),
            max_cable_length_error=float(data["max_cable_length_error"]),
            max_tracking_deviation=float(data["max_tracking_deviation"]),
            timing_tolerance=TimingTolerance(**data["timing_tolerance"]),
            early_legs=tuple((int(d), int(k)) for d, k in data["early_legs"]),
            items_per_drone=tuple(int(n) for n in data["items_per_drone"]),
            release=Release(**data["release"]),
            obstacle_clearance=float(data["obstacle_clearance"]),
            position_error=PositionErrorModel.model_validate(data["position_error"]),
            lift_off=VerticalLeg.from_dict(data["lift_off"]) if data["lift_off"] else None,
            set_down=SetDown.from_dict(data["set_down"]) if data["set_down"] else None,
            robust_statics_margin=data.get("robust_statics_margin"),
            robust_statics_limit=data.get("robust_statics_limit"),
            robust_margin=data.get("robust_margin"),
        )


def raised_clearance(attempt: dict[str, Any]) -> bool:
    """Whether an entry of :attr:`TaskOutcome.attempts` was a path planned again with more
    clearance (``mission.robust_clearance``; it names the clearance), not one whose
    missions failed their check."""
    return "clearance" in attempt


@dataclass(frozen=True)
class TaskOutcome:
    """What a task's run produced (summary.json; the service stores it as the task's
    result). ``artifacts`` maps names to files relative to the directory."""

    status: Status
    reason: str = ""
    planner_status: str = ""
    planner_statistics: dict[str, Any] = field(default_factory=dict)
    metrics: PathMetrics | None = None
    mission: MissionSummary | None = None
    artifacts: dict[str, str] = field(default_factory=dict)
    #: paths planned before the last: seed and reason; whose missions failed their check,
    #: or too close for the drones' errors (:func:`raised_clearance`)
    attempts: tuple[dict[str, Any], ...] = ()

    def as_dict(self) -> dict[str, Any]:
        return {
            "status": self.status,
            "reason": self.reason,
            "planner_status": self.planner_status,
            "planner_statistics": dict(self.planner_statistics),
            "metrics": self.metrics.as_dict() if self.metrics else None,
            "mission": self.mission.as_dict() if self.mission else None,
            "artifacts": dict(self.artifacts),
            "attempts": [dict(a) for a in self.attempts],
        }

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> TaskOutcome:
        return cls(
            status=data["status"],
            reason=data.get("reason", ""),
            planner_status=data.get("planner_status", ""),
            planner_statistics=dict(data.get("planner_statistics") or {}),
            metrics=PathMetrics(**data["metrics"]) if data.get("metrics") else None,
            mission=MissionSummary.from_dict(data["mission"]) if data.get("mission") else None,
            artifacts=dict(data.get("artifacts") or {}),
            attempts=tuple(data.get("attempts") or ()),
        )


@dataclass(frozen=True)
class Tracks:
    """tracks.json: the timed waypoints and everything the flight will be judged against.

    Waypoint arrays have W rows; the dense plan (``dense_time``, ``dense_configurations``)
    is the planned path on mission time, sampled as finely as the checks sampled it; the
    modelled motions are stored at :data:`STORED_MOTION_RATE_HZ`."""

    time: NDArray[np.float64]  #: (W,) mission time of each waypoint [s from the release]
    configurations: NDArray[np.float64]  #: (W, 9)
    drones_enu: NDArray[np.float64]  #: (W, 3, 3) the planned drones [m]
    drones_stored_enu: NDArray[np.float64]  #: (W, 3, 3) as ArduPilot stores the waypoints
    drones_wgs84: NDArray[np.float64]  #: (W, 3, 3) latitude, longitude [deg], AMSL [m]
    speed_limits: tuple[tuple[SpeedLimits, ...], ...]  #: [drone][leg]
    annotations: tuple[dict[str, Any], ...]  #: per waypoint (:mod:`.annotations` records)
    timing_tolerance: TimingTolerance
    dense_time: NDArray[np.float64]  #: (N,) [s]
    dense_configurations: NDArray[np.float64]  #: (N, 9)
    motion: DroneMotion  #: the autopilots' targets as the mission model flies them
    vehicle_motion: DroneMotion  #: the modelled vehicles following those targets
    lift_off: VerticalLeg | None
    set_down: SetDown | None

    def as_dict(self) -> dict[str, Any]:
        return {
            "time": self.time.tolist(),
            "configurations": self.configurations.tolist(),
            "drones_enu": self.drones_enu.tolist(),
            "drones_stored_enu": self.drones_stored_enu.tolist(),
            "drones_wgs84": self.drones_wgs84.tolist(),
            "speed_limits": [[asdict(limit) for limit in row] for row in self.speed_limits],
            "annotations": list(self.annotations),
            "timing_tolerance": self.timing_tolerance.as_dict(),
            "dense": {
                "time": self.dense_time.tolist(),
                "configurations": self.dense_configurations.tolist(),
            },
            "motion": self.motion.decimated(STORED_MOTION_RATE_HZ).as_dict(),
            "vehicle_motion": self.vehicle_motion.decimated(STORED_MOTION_RATE_HZ).as_dict(),
            "lift_off": self.lift_off.as_dict() if self.lift_off else None,
            "set_down": self.set_down.as_dict() if self.set_down else None,
        }

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> Tracks:
        """Raises ValueError where the arrays' shapes do not fit together (an edited file)."""
        tracks = cls(
            time=np.array(data["time"], dtype=float),
            configurations=np.array(data["configurations"], dtype=float),
            drones_enu=np.array(data["drones_enu"], dtype=float),
            drones_stored_enu=np.array(data["drones_stored_enu"], dtype=float),
            drones_wgs84=np.array(data["drones_wgs84"], dtype=float),
            speed_limits=tuple(
                tuple(SpeedLimits(**limit) for limit in row) for row in data["speed_limits"]
            ),
            annotations=tuple(data["annotations"]),
            timing_tolerance=TimingTolerance(**data["timing_tolerance"]),
            dense_time=np.array(data["dense"]["time"], dtype=float),
            dense_configurations=np.array(data["dense"]["configurations"], dtype=float),
            motion=DroneMotion.from_dict(data["motion"]),
            vehicle_motion=DroneMotion.from_dict(data["vehicle_motion"]),
            lift_off=VerticalLeg.from_dict(data["lift_off"]) if data["lift_off"] else None,
            set_down=SetDown.from_dict(data["set_down"]) if data["set_down"] else None,
        )
        tracks._check_shapes()
        return tracks

    def _check_shapes(self) -> None:
        w, n = len(self.time), len(self.dense_time)
        shapes: dict[str, tuple[NDArray[np.float64], tuple[int, ...]]] = {
            "time": (self.time, (w,)),
            "configurations": (self.configurations, (w, 9)),
            "drones_enu": (self.drones_enu, (w, 3, 3)),
            "drones_stored_enu": (self.drones_stored_enu, (w, 3, 3)),
            "drones_wgs84": (self.drones_wgs84, (w, 3, 3)),
            "dense.time": (self.dense_time, (n,)),
            "dense.configurations": (self.dense_configurations, (n, 9)),
        }
        for name, motion in (("motion", self.motion), ("vehicle_motion", self.vehicle_motion)):
            m = len(motion.time)
            shapes[f"{name}.time"] = (motion.time, (m,))
            shapes[f"{name}.drones_enu"] = (motion.drones, (m, 3, 3))
        for name, (array, shape) in shapes.items():
            if len(array) < 2:
                raise ValueError(f"{name} has {len(array)} rows, fewer than 2")
            if array.shape != shape:
                raise ValueError(f"{name} has shape {array.shape}, not {shape}")
            if not np.all(np.isfinite(array)):
                raise ValueError(f"{name} holds a value that is not a finite number")
        for name, time in (("time", self.time), ("dense.time", self.dense_time),
                           ("motion.time", self.motion.time),
                           ("vehicle_motion.time", self.vehicle_motion.time)):  # fmt: skip
            if np.any(np.diff(time) < 0):
                raise ValueError(f"{name} decreases")
        if len(self.speed_limits) != len(DRONES):
            raise ValueError(f"speed_limits has {len(self.speed_limits)} rows, not {len(DRONES)}")


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
