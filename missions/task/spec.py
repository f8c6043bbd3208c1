"""A manipulation task: system, scene, start and goal, planner and mission options.

The same schema is the body of ``POST /v1/tasks`` and the file ``flycrane plan`` reads.
:func:`resolve_task` turns it into a planning problem and checks start and goal, raising
errors that name the field (preset names, system or scene fields) or the violated
constraint and colliding bodies (start and goal).
"""

from __future__ import annotations

import json
import tomllib
import unicodedata
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray
from pydantic import BaseModel, ConfigDict, Field, ValidationError, field_validator

from flycrane.errors import FieldProblem, InputError
from flycrane.model.system_spec import SystemSpec, problems_from_validation_error, system_preset
from flycrane.planning.algorithms.bitrrt import MESH_REASON, MeshScene
from flycrane.planning.planners import PlannerOptions
from flycrane.planning.poses import configuration_from_pose
from flycrane.planning.problem import PlanningProblem
from flycrane.quantities import Configuration, Orientation, Point
from flycrane.world.scene import Mesh, SceneSpec, list_scenes, load_scene
from missions.options import MissionOptions
from missions.position_error import position_error_model
from missions.trajectory.vertical_legs import VerticalLeg, clear_end


class PlatformPose(BaseModel):
    """A start or goal given as the platform's pose; the alphas of least cost are chosen."""

    model_config = ConfigDict(frozen=True, extra="forbid", allow_inf_nan=False)

    position: Point = Field(description="P [m], world frame")
    orientation: Orientation = Field((0.0, 0.0, 0.0), description="(phi, theta, sigma) [rad]")


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


@dataclass(frozen=True)
class ResolvedTask:
    """A task made concrete: the problem and the checked configurations to plan between.

    Where the given start or goal lies within the obstacle clearance of a surface, the plan
    starts or ends at the pose above it, and ``lift_off`` / ``set_down`` is the vertical leg
    the mission flies between the two (:mod:`missions.trajectory.vertical_legs`)."""

    task: TaskSpec
    problem: PlanningProblem
    start: NDArray[np.float64]
    goal: NDArray[np.float64]
    lift_off: VerticalLeg | None = None
    set_down: VerticalLeg | None = None


def task_from_dict(data: dict, source: str | None = None) -> TaskSpec:
    """Validate a mapping as a task, raising :class:`InputError` naming the field."""
    try:
        return TaskSpec.model_validate(data)
    except ValidationError as error:
        raise InputError(problems_from_validation_error(error), source) from None


def load_task(path: str | Path) -> tuple[TaskSpec, Path]:
    """A task from a .json or .toml file, and the directory relative paths start from."""
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
        data = tomllib.loads(text) if path.suffix.lower() == ".toml" else json.loads(text)
    except (OSError, ValueError) as error:
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


def task_specs(
    task: TaskSpec, base_dir: Path | None = None
) -> tuple[SystemSpec, SceneSpec, Path | None]:
    """The task's system and scene with presets loaded, and the directory its scene's mesh
    files are relative to.

    Raises
    ------
    InputError
        Unknown system or scene preset (field ``system`` or ``scene``).
    """
    system = system_preset(task.system) if isinstance(task.system, str) else task.system
    if not isinstance(task.scene, str):
        return system, task.scene, base_dir
    try:
        scene, scene_dir = load_scene(task.scene)
    except InputError as error:
        raise InputError([FieldProblem("scene", p.reason) for p in error.problems]) from None
    return system, scene, scene_dir


def resolve_task(task: TaskSpec, base_dir: Path | None = None) -> ResolvedTask:
    """Build the problem and check start and goal (every error names its field).

    Raises
    ------
    InputError
        Unknown preset, or a start/goal of the wrong shape.
    InvalidConfigurationError
        Start or goal infeasible, out of bounds or in collision (``what`` says which).
    """
    system, scene, scene_dir = task_specs(task, base_dir)
    # The plan keeps the clearance the position-error model asks for (or the scene's, if
    # larger): docs/missions.md "Clearance".
    clearance = max(
        scene.collision.obstacle_clearance,
        position_error_model(task.mission.position_error).obstacle_clearance,
    )
    if clearance != scene.collision.obstacle_clearance:
        try:
            scene = scene.model_copy(
                update={
                    "collision": scene.collision.model_copy(
                        update={"obstacle_clearance": clearance}
                    )
                }
            )
            scene = SceneSpec.model_validate(scene.model_dump())
        except ValidationError as error:
            raise InputError(
                [FieldProblem("mission.position_error", p.reason)
                 for p in problems_from_validation_error(error)]
            ) from None  # fmt: skip
    problem = PlanningProblem.from_scene(scene, system, scene_dir)
    try:
        task.planner.algorithm_for(problem.validity.has_meshes)
    except MeshScene:
        raise InputError([FieldProblem("planner.algorithm", MESH_REASON)]) from None
    ends, legs = [], []
    ends_given = (("start", task.start, scene.start), ("goal", task.goal, scene.goal))
    for what, given, default in ends_given:
        if isinstance(given, PlatformPose):
            real = problem.validity.with_clearance(0.0)
            q = configuration_from_pose(
                problem.space, real, given.position, given.orientation, what
            )
        else:
            q = np.array(default if given is None else given, dtype=float)
        approach = task.mission.set_down_approach if what == "goal" else 0.0
        planned, leg = clear_end(q, problem.validity, what, approach)
        ends.append(planned)
        legs.append(leg)
    return ResolvedTask(task, problem, ends[0], ends[1], lift_off=legs[0], set_down=legs[1])
