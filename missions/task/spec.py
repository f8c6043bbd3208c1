"""A manipulation task: system, scene, start and goal, planner and mission options.

The same schema is the body of ``POST /v1/tasks`` and the file ``flycrane plan`` reads;
:mod:`missions.task.resolve` makes it a planning problem.
"""

from __future__ import annotations

import json
import tomllib
import unicodedata
from pathlib import Path

from pydantic import BaseModel, ConfigDict, Field, ValidationError, field_validator

from flycrane.errors import FieldProblem, InputError
from flycrane.model.system_spec import SystemSpec, problems_from_validation_error
from flycrane.planning.planners import PlannerOptions
from flycrane.quantities import Configuration, PlatformOrientation, Point
from flycrane.user_files import read_text
from flycrane.world.scene import Mesh, SceneSpec, list_scenes
from missions.options import MissionOptions


class PlatformPose(BaseModel):
    """A start or goal given as the platform's pose; the alphas of least cost are chosen."""

    model_config = ConfigDict(frozen=True, extra="forbid", allow_inf_nan=False)

    position: Point = Field(description="P [m], world frame")
    orientation: PlatformOrientation = Field(
        (0.0, 0.0, 0.0), description="(phi, theta, sigma) [rad], theta in [0, pi]"
    )


class TaskSpec(BaseModel):
    """Everything needed to plan and export a FlyCrane manipulation."""

    model_config = ConfigDict(frozen=True, extra="forbid", allow_inf_nan=False)

    name: str = Field("", max_length=200, description="text without control characters")
    system: str | SystemSpec = Field("benchmark", description="preset name or description")
    scene: str | SceneSpec = Field("rescue", description="preset name or inline scene")
    start: Configuration | PlatformPose | None = Field(None, description="None: the scene's")
    goal: Configuration | PlatformPose | None = Field(None, description="None: the scene's")
    planner: PlannerOptions = Field(default_factory=PlannerOptions)
    mission: MissionOptions = Field(default_factory=MissionOptions)

    @field_validator("name")
    @classmethod
    def _printable(cls, value: str) -> str:
        """A name titles plots and logs: text, not control characters."""
        bad = next((c for c in value if unicodedata.category(c) == "Cc"), None)
        if bad is not None:
            raise ValueError(f"must not contain control characters (found U+{ord(bad):04X})")
        return value


def task_from_dict(data: dict, source: str | None = None) -> TaskSpec:
    """Validate a mapping as a task, raising :class:`InputError` naming the field."""
    if not isinstance(data, dict):
        kind = type(data).__name__
        raise InputError([FieldProblem("task", f"must be an object of fields, got {kind}")], source)
    try:
        return TaskSpec.model_validate(data)
    except ValidationError as error:
        raise InputError(problems_from_validation_error(error), source) from None


def load_task(path: str | Path) -> tuple[TaskSpec, Path]:
    """A task from a .json or .toml file, and the directory relative paths start from."""
    path = Path(path)
    try:
        text = read_text(path)
    except InputError as error:
        raise InputError(error.problems, str(path)) from None
    try:
        data = tomllib.loads(text) if path.suffix.lower() == ".toml" else json.loads(text)
    except ValueError as error:
        raise InputError([FieldProblem("file", str(error))], str(path)) from None
    return task_from_dict(data, str(path)), path.parent


def served_task_problems(task: TaskSpec) -> list[FieldProblem]:
    """Why a task may not be run as received over a network (empty: it may).

    Such a task names files on nobody's behalf: its scene is a preset name or inline, and its
    inline meshes carry their vertices (a mesh file or a scene path would be read from the
    server's disk, where a name can be a device, a FIFO or someone else's file).
    """
    if isinstance(task.scene, str):
        if task.scene in list_scenes():
            return []
        known = ", ".join(list_scenes())
        return [FieldProblem("scene", f"no scene {task.scene!r} among the presets; known: {known}")]
    shapes = [("obstacles", i, s) for i, s in enumerate(task.scene.obstacles)]
    shapes += [("payload.shapes", i, s) for i, s in enumerate(task.scene.payload.shapes)]
    return [
        FieldProblem(
            f"scene.{where}[{index}].file",
            "mesh files cannot be referenced here; give vertices and faces",
        )
        for where, index, shape in shapes
        if isinstance(shape, Mesh) and shape.file is not None
    ]


def require_served_task(task: TaskSpec) -> None:
    """Raise :class:`InputError` with :func:`served_task_problems` if there are any."""
    problems = served_task_problems(task)
    if problems:
        raise InputError(problems)
