"""The plan viewer's data: one JSON document built from a task's stored artifacts.

:func:`view_document` reads ``tracks.json`` (the dense planned track, the waypoints),
``summary.json`` and, where a flight report left one, ``flown.json``; with the task's scene
and system it computes every pose the page draws with the project's own kinematics, statics
and direct kinematics, so the browser only places what it is given. The shape of the
document is described field by field in docs/viewer.md; all numbers are SI, in the task's
local ENU frame (z up), quaternions (x, y, z, w), drones and cables in the design's order.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy.spatial.transform import Rotation

from flycrane.errors import FlyCraneError
from flycrane.model.cable_system import CABLE_DRONE, CableSystem
from flycrane.model.kinematics import (
    drone_positions_from_configuration,
    matrix_from_tilt_torsion,
    platform_points_from_configuration,
)
from flycrane.world.bodies import platform_prism
from flycrane.world.scene import Mesh, SceneSpec, Shape
from missions.task.directory import TaskDirectory, TaskDirectoryError
from missions.task.documents import TaskOutcome, Tracks
from missions.task.resolve import task_specs
from missions.task.spec import TaskSpec
from missions.trajectory.annotations import annotate
from missions.trajectory.tracks import samples_at_rate
from missions.viewer.flown import FlownTrack, FlownTrackError, load_flown, reconstruct

#: Name and version of the document's shape (docs/viewer.md).
VIEW_FORMAT = "flycrane.view/1"

#: Decimals kept in the document: 1 micrometre, 1e-7 of a quaternion, 10 micronewtons.
#: Far below anything a page can show, and they keep a document small.
POSITION_DECIMALS, ROTATION_DECIMALS, FORCE_DECIMALS = 6, 7, 5


class ViewUnavailableError(FlyCraneError):
    """A task's artifacts cannot be viewed (not planned to the end); names the file."""


def _plain(values: Any, decimals: int) -> list:
    """Rounded nested lists, with None where a value is not finite (JSON has no inf)."""
    array = np.asarray(values, dtype=float)
    plain = np.round(array, decimals).astype(object)
    plain[~np.isfinite(array)] = None
    return plain.tolist()


def _quaternions(angles: NDArray[np.float64]) -> NDArray[np.float64]:
    """Quaternions (..., 4) as (x, y, z, w) of tilt-and-torsion angles (..., 3)."""
    matrices = matrix_from_tilt_torsion(angles)
    return Rotation.from_matrix(matrices.reshape(-1, 3, 3)).as_quat().reshape(*angles.shape[:-1], 4)


def shape_document(shape: Shape, base_dir: Path | None) -> dict[str, Any]:
    """A scene shape as the page draws it: kind, placement and dimensions (meshes as
    triangles, scaled, whether inline or from a file)."""
    placed = {
        "kind": shape.kind,
        "name": shape.name,
        "center": list(shape.center),
        "quaternion": _plain(_quaternions(np.array(shape.rotation)), ROTATION_DECIMALS),
    }
    if isinstance(shape, Mesh):
        vertices, faces = shape.triangles(base_dir)
        return {**placed, "vertices": _plain(vertices, POSITION_DECIMALS), "faces": faces.tolist()}
    sizes = shape.model_dump(include={"size", "radius", "height"})
    return {**placed, **{k: list(v) if isinstance(v, tuple) else v for k, v in sizes.items()}}


def _crane_document(system: CableSystem, scene: SceneSpec, base_dir: Path | None) -> dict:
    vertices, faces = platform_prism(system, scene.collision.platform_thickness)
    platform = {
        "kind": "mesh",
        "name": "platform",
        "center": [0.0, 0.0, 0.0],
        "quaternion": [0.0, 0.0, 0.0, 1.0],
        "vertices": _plain(vertices, POSITION_DECIMALS),
        "faces": faces.tolist(),
    }
    return {
        "platform": platform,
        "payload": [shape_document(s, base_dir) for s in scene.payload.shapes],
        "drone_radius": scene.collision.drone_radius,
        "cable_radius": scene.collision.cable_radius,
        "cable_lengths": system.cable_lengths.tolist(),
        "cable_drone": [k + 1 for k in CABLE_DRONE],
    }


def _limit_lines(values: NDArray[np.float64], name: str, item: str) -> list[dict[str, Any]]:
    """One line per distinct limit value, labelled with the items (cables, drones) it bounds."""
    lines = []
    for value in np.unique(values):
        items = [str(i + 1) for i in np.flatnonzero(values == value)]
        which = f"{item}s {', '.join(items)}" if len(items) < len(values) else f"all {item}s"
        lines.append({"label": f"{name} = {value:g} N ({which})", "value": float(value)})
    return lines


def frames_document(
    system: CableSystem,
    time: NDArray[np.float64],
    q: NDArray[np.float64],
    drones: NDArray[np.float64],
    valid: NDArray[np.bool_] | None = None,
) -> dict[str, Any]:
    """Poses and statics at F frames: platform pose, drones, cable end points (platform
    point, drone), tensions with their ranges, thrusts and worst cases, cost.

    ``drones`` (F, 3, 3) are where the cables end: the kinematics' for a plan, the measured
    ones for a flight. Frames not ``valid`` (no reconstructed pose) have None for the
    platform pose, the cables and the statics.
    """
    valid = np.ones(len(time), bool) if valid is None else valid
    b = platform_points_from_configuration(system, q)
    cables = np.stack([b, drones[:, CABLE_DRONE, :]], axis=2)  # (F, 6, 2, 3)
    statics = annotate(system, time, q)

    def masked(values: NDArray, decimals: int) -> list:
        rows = _plain(values, decimals)
        return [row if ok else None for row, ok in zip(rows, valid, strict=True)]

    return {
        "time": _plain(time, POSITION_DECIMALS),
        "platform_position": masked(q[:, :3], POSITION_DECIMALS),
        "platform_quaternion": masked(_quaternions(q[:, 3:6]), ROTATION_DECIMALS),
        "drones": _plain(drones, POSITION_DECIMALS),
        "cables": masked(cables, POSITION_DECIMALS),
        "tension": masked(statics.tension, FORCE_DECIMALS),
        "tension_low": masked(statics.tension_low, FORCE_DECIMALS),
        "tension_high": masked(statics.tension_high, FORCE_DECIMALS),
        "thrust": masked(statics.thrust_magnitude, FORCE_DECIMALS),
        "thrust_bound": masked(statics.thrust_bound, FORCE_DECIMALS),
        "cost": masked(statics.cost, 3),
    }


def _planned_frames(
    system: CableSystem, tracks: Tracks, rate: float, max_frames: int
) -> dict[str, Any]:
    """The dense planned track at about ``rate`` Hz (fewer frames past ``max_frames``),
    always including the waypoints' samples."""
    time, q, waypoint_time = tracks.dense_time, tracks.dense_configurations, tracks.time
    at = np.clip(np.searchsorted(time, waypoint_time), 0, len(time) - 1)
    if not np.allclose(time[at], waypoint_time, rtol=0.0, atol=1e-9):
        raise ViewUnavailableError("tracks.json: waypoint times are not samples of the track")
    rate = min(rate, max_frames / max(float(time[-1] - time[0]), 1e-9))
    frames = np.union1d(samples_at_rate(time, rate), at)
    document = frames_document(
        system, time[frames], q[frames], drone_positions_from_configuration(system, q[frames])
    )
    document["waypoint_frames"] = np.searchsorted(frames, at).tolist()
    return document


def _flown_frames(
    system: CableSystem, flown: FlownTrack, rate: float, max_frames: int
) -> dict[str, Any]:
    time = np.asarray(flown.time)
    rate = min(rate, max_frames / max(float(time[-1] - time[0]), 1e-9))
    load = reconstruct(system, flown, samples_at_rate(time, rate))
    document = frames_document(system, load.time, load.q, load.drones, load.converged)
    return {"source": flown.source, "converged": load.converged.tolist(), **document}


def _facts(summary: TaskOutcome, scene: SceneSpec, flown: FlownTrack | None) -> list[dict]:
    """What the page's header lists: label and preformatted value."""
    mission, metrics = summary.mission, summary.metrics
    seconds = summary.planner_statistics.get("time", 0)
    # the plan's: the position-error model's clearance where it is more than the scene's
    clearance = mission.obstacle_clearance if mission else scene.collision.obstacle_clearance
    facts = [
        ("scene", scene.name),
        ("planner", f"{summary.planner_status or '?'} in {seconds:.2f} s"),
        (
            "mission",
            f"{mission.waypoints} waypoints, {mission.duration:.2f} s"
            if mission
            else "? waypoints, 0.00 s",
        ),
        ("max cost", f"{metrics.max_cost if metrics else float('nan'):.4g}"),
        ("obstacle clearance", f"{clearance:g} m"),
    ]
    if flown is not None:
        facts.append(("flown", f"{flown.source}, {flown.time[-1] - flown.time[0]:.2f} s"))
    return [{"label": label, "value": value} for label, value in facts]


def view_document(
    task: TaskSpec,
    task_dir: str | Path,
    base_dir: Path | None = None,
    title: str = "",
    rate: float = 20.0,
    max_frames: int = 3000,
    flown_dir: Path | None = None,
) -> dict[str, Any]:
    """The viewer's JSON document of a planned task (module docstring, docs/viewer.md).

    Parameters
    ----------
    task : TaskSpec
        The task as submitted (its system and scene are loaded as when it was planned).
    task_dir : path
        Where its artifacts are.
    base_dir : path, optional
        What the task's inline scene's mesh files are relative to.
    rate : float
        Frames per second of track shown [Hz]; lowered so that a track has at most about
        ``max_frames`` frames (the waypoints' samples are always frames).
    flown_dir : path, optional
        Where a flight report left ``flown.json`` (default: ``task_dir``).

    Raises
    ------
    ViewUnavailableError
        The task has no tracks (it failed or was cancelled).
    InputError
        Unknown presets, or an inline scene's mesh file that cannot be read.
    """
    task_dir = Path(task_dir)
    system_spec, scene, scene_dir = task_specs(task, base_dir)
    system = CableSystem.from_spec(scene.system_spec(system_spec))
    directory = TaskDirectory(task_dir)
    try:
        tracks, summary = directory.tracks(), directory.summary()
    except TaskDirectoryError as error:
        raise ViewUnavailableError(f"{error} (the task was not planned to the end)") from None
    notes = []
    try:
        flown = load_flown(task_dir if flown_dir is None else flown_dir)
    except FlownTrackError as error:
        flown = None
        notes.append(f"flown data not shown: {error}")
    return {
        "format": VIEW_FORMAT,
        "title": title or task.name or scene.name,
        "facts": _facts(summary, scene, flown),
        "notes": notes,
        "scene": {
            "name": scene.name,
            "description": scene.description,
            "ground": scene.ground,
            "obstacles": [shape_document(s, scene_dir) for s in scene.obstacles],
        },
        "crane": _crane_document(system, scene, scene_dir),
        "limits": {
            "tension": _limit_lines(system.tension_min, "f_lo", "cable")
            + _limit_lines(system.tension_max, "f_hi", "cable"),
            "thrust": _limit_lines(system.max_thrusts, "h", "drone"),
        },
        "planned": _planned_frames(system, tracks, rate, max_frames),
        "flown": None if flown is None else _flown_frames(system, flown, rate, max_frames),
    }
