"""A task made concrete: its problem, the planner that runs, the checkers of each clearance,
and the checked start and goal.

:func:`resolve_task` raises errors that name the field (preset names, system or scene
fields) or the violated constraint and colliding bodies (start and goal). Everything a
task's run needs more than once is resolved here once.
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from dataclasses import dataclass
from functools import cached_property, partial
from pathlib import Path

import numpy as np
from numpy.typing import NDArray
from pydantic import ValidationError

from flycrane.errors import FieldProblem, InputError, SystemSpecError
from flycrane.model.robust_statics import RobustStatics
from flycrane.model.system_spec import SystemSpec, problems_from_validation_error, system_preset
from flycrane.planning.algorithms.bitrrt import MESH_REASON, PayloadMeshes
from flycrane.planning.planners import Algorithm
from flycrane.planning.poses import configuration_from_pose
from flycrane.planning.problem import PlanningProblem
from flycrane.planning.robust_clearance import RobustClearance
from flycrane.planning.validity import InvalidConfigurationError, ValidityChecker
from flycrane.world.scene import SceneSpec, list_scenes, load_scene
from missions.options import MAX_MISSION_DURATION_S
from missions.position_error import PositionErrorModel, position_error_model
from missions.task.spec import PlatformPose, TaskSpec
from missions.trajectory.tracks import least_duration
from missions.trajectory.vertical_legs import VerticalLeg, clear_end, hold_height

logger = logging.getLogger(__name__)


@dataclass(frozen=True)
class Checkers:
    """The task's validity at each clearance it is judged by (docs/missions.md
    "Clearance"): the plan keeps the whole obstacle clearance, the mission's legs may use
    half of it (the other half is the flight's), and a flight is judged on the real
    obstacles."""

    planning: ValidityChecker
    legs: ValidityChecker
    real: ValidityChecker

    @classmethod
    def of(cls, planning: ValidityChecker) -> Checkers:
        clearance = planning.scene.collision.obstacle_clearance
        return cls(planning, planning.with_clearance(clearance / 2), planning.with_clearance(0.0))


@dataclass(frozen=True)
class ResolvedTask:
    """A task made concrete: the problem and the checked configurations to plan between.

    Where the given start or goal lies within the obstacle clearance of a surface, the plan
    starts or ends at the pose above it, and ``lift_off`` / ``set_down`` is the vertical leg
    the mission flies between the two (:mod:`missions.trajectory.vertical_legs`)."""

    task: TaskSpec
    problem: PlanningProblem
    algorithm: Algorithm  #: the planner that runs in this scene
    checkers: Checkers
    start: NDArray[np.float64]
    goal: NDArray[np.float64]
    position_error: PositionErrorModel  #: ``task.mission.position_error``, resolved
    lift_off: VerticalLeg | None = None
    set_down: VerticalLeg | None = None
    scene_dir: Path | None = None  #: what the scene's mesh files are relative to

    @cached_property
    def robust(self) -> RobustClearance:
        """The real obstacles' gaps against the bound of the position-error model's errors."""
        model = self.position_error
        common = (model.common_horizontal, model.common_vertical)
        return RobustClearance(self.checkers.real, common, model.own)

    def robust_statics(self, path: NDArray[np.float64]) -> RobustStatics:
        """The statics margins along ``path`` (at the robust clearance's resolution) against
        what the position-error model's own drone errors can take of them."""
        samples = self.problem.space.discretize_path(path, self.robust.resolution)
        return RobustStatics.of(self.problem.system, samples, self.position_error.own)

    def self_contained(self) -> TaskSpec:
        """The task with its system, scene, start, goal and planner written out, so that
        the task's directory alone says what was planned and plans it again: the start and
        goal as given (a pose as its configuration), not raised above a surface, so that
        the lift-off and set-down are planned again too."""
        task, problem = self.task, self.problem
        start = self.start if self.lift_off is None else self.lift_off.low
        goal = self.goal if self.set_down is None else self.set_down.low
        return task.model_copy(
            update={
                "planner": task.planner.model_copy(update={"algorithm": self.algorithm}),
                "system": problem.system.spec,
                "scene": problem.scene,
                "start": tuple(float(v) for v in start),
                "goal": tuple(float(v) for v in goal),
            }
        )


def task_specs(
    task: TaskSpec, base_dir: Path | None = None
) -> tuple[SystemSpec, SceneSpec, Path | None]:
    """The task's system and scene with presets loaded, and the directory its scene's mesh
    files are relative to. A scene file's path is relative to ``base_dir`` (the task
    file's folder), as a scene's mesh files are to the scene file's.

    Raises
    ------
    InputError
        Unknown system or scene preset (field ``system`` or ``scene``).
    """
    system = system_preset(task.system) if isinstance(task.system, str) else task.system
    if not isinstance(task.scene, str):
        return system, task.scene, base_dir
    source = task.scene
    if base_dir is not None and source not in list_scenes():
        source = str(base_dir / source)  # an absolute path stays itself
    try:
        scene, scene_dir = load_scene(source)
    except InputError as error:
        where = f"{error.source}: " if error.source else ""
        problems = [
            FieldProblem(
                "scene", p.reason if p.field == "scene" else f"{where}{p.field}: {p.reason}"
            )
            for p in error.problems
        ]
        raise InputError(problems) from None
    return system, scene, scene_dir


def resolve_task(
    task: TaskSpec, base_dir: Path | None = None, clearance: float = 0.0
) -> ResolvedTask:
    """Build the problem and check start and goal (every error names its field); the plan
    keeps at least ``clearance`` [m] from the obstacles.

    Raises
    ------
    InputError
        Unknown preset, a start/goal of the wrong shape, or a mission that could not last
        less than :data:`~missions.options.MAX_MISSION_DURATION_S` at the task's speed.
    InvalidConfigurationError
        Start or goal infeasible, out of bounds or in collision (``what`` says which).
    """
    system, scene, scene_dir = task_specs(task, base_dir)
    # The plan keeps the clearance the position-error model asks for (or the scene's, if
    # larger): docs/missions.md "Clearance".
    model = position_error_model(task.mission.position_error)
    clearance = max(scene.collision.obstacle_clearance, model.obstacle_clearance, clearance)
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
    try:
        problem = PlanningProblem.from_scene(scene, system, scene_dir)
    except SystemSpecError as error:
        raise error.under("system") from None
    try:
        algorithm = task.planner.algorithm_for(problem.validity.payload_meshes)
    except PayloadMeshes:
        raise InputError([FieldProblem("planner.algorithm", MESH_REASON)]) from None
    checkers = Checkers.of(problem.validity)
    ends, legs, hold = [], [], hold_height(problem, model, clearance)
    ends_given = (("start", task.start, scene.start), ("goal", task.goal, scene.goal))
    for what, given, default in ends_given:
        approach = task.mission.set_down_approach if what == "goal" else 0.0
        raise_end = partial(
            clear_end, validity=checkers.planning, real=checkers.real, what=what,
            approach=approach, hold=hold,
        )  # fmt: skip
        raised: dict[bytes, tuple[NDArray[np.float64], VerticalLeg | None]] = {}
        if isinstance(given, PlatformPose):
            q = configuration_from_pose(
                problem.space, checkers.real, given.position, given.orientation, what,
                accept=partial(_raises_clear, raise_end, raised),
            )  # fmt: skip
        else:
            q = np.array(default if given is None else given, dtype=float)
        planned, leg = raised.get(q.tobytes()) or raise_end(q)
        ends.append(planned)
        legs.append(leg)
    least = least_duration(problem.system, np.stack(ends), task.mission)
    speed = task.mission.max_drone_speed
    if least > MAX_MISSION_DURATION_S:
        raise InputError([FieldProblem(
            "mission.max_drone_speed",
            f"from start to goal a drone travels at least {least * speed:.0f} m: at "
            f"{speed:g} m/s the mission would last at least {least:.0f} s, more than the "
            f"{MAX_MISSION_DURATION_S:.0f} s a mission may last",
        )])  # fmt: skip
    return ResolvedTask(
        task, problem, algorithm, checkers, ends[0], ends[1], model, lift_off=legs[0],
        set_down=legs[1], scene_dir=scene_dir,
    )  # fmt: skip


def _raises_clear(
    raise_end: Callable[[NDArray[np.float64]], tuple[NDArray[np.float64], VerticalLeg | None]],
    raised: dict[bytes, tuple[NDArray[np.float64], VerticalLeg | None]],
    q: NDArray[np.float64],
) -> bool:
    """Whether the end ``q`` can be planned from (or to), raised clear where it needs; the
    raised end goes into ``raised`` under ``q``'s bytes."""
    try:
        raised[q.tobytes()] = raise_end(q)
    except InvalidConfigurationError:
        return False
    return True


def resolve_raised(
    task: TaskSpec, base_dir: Path | None, resolved: ResolvedTask, margin: float, step: float
) -> tuple[ResolvedTask, float] | None:
    """The task resolved keeping ``step`` [m] more clearance than a path whose robust
    ``margin`` [m] fell short, and that clearance; None where the ends do not keep it."""
    kept = resolved.problem.scene.collision.obstacle_clearance
    clearance = round(kept - margin + step, 3)
    try:
        return resolve_task(task, base_dir, clearance), clearance
    except (InputError, InvalidConfigurationError) as error:
        logger.info("robust margin %.3f m; %.3f m refused: %s", margin, clearance, error)
        return None
