"""A planning problem assembled from a scene: system, state space, validity, start, goal."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from flycrane.model.cable_system import CableSystem
from flycrane.model.system_spec import SystemSpec
from flycrane.planning.state_space import ConfigurationSpace
from flycrane.planning.validity import ValidityChecker
from flycrane.world.scene import SceneSpec, load_scene


@dataclass(frozen=True)
class PlanningProblem:
    """Everything a planner needs, built once per (system, scene)."""

    system: CableSystem
    scene: SceneSpec
    space: ConfigurationSpace
    validity: ValidityChecker
    start: NDArray[np.float64]
    goal: NDArray[np.float64]

    @classmethod
    def from_scene(
        cls,
        scene: SceneSpec,
        system: SystemSpec | None = None,
        base_dir: Path | None = None,
        start: NDArray[np.float64] | None = None,
        goal: NDArray[np.float64] | None = None,
    ) -> PlanningProblem:
        """The problem of a scene; the system gets the scene's payload mass and centre of
        mass; start and goal default to the scene's."""
        model = CableSystem.from_spec(scene.system_spec(system))
        b = scene.bounds
        space = ConfigurationSpace.for_system(
            model,
            b.position_low,
            b.position_high,
            b.max_tilt,
            b.alpha_low,
            b.alpha_high,
            b.sigma_low,
            b.sigma_high,
        )
        return cls(
            system=model,
            scene=scene,
            space=space,
            validity=ValidityChecker(model, scene, space, base_dir),
            start=np.array(scene.start if start is None else start, dtype=float),
            goal=np.array(scene.goal if goal is None else goal, dtype=float),
        )

    @classmethod
    def named(cls, name: str) -> PlanningProblem:
        """A shipped scene by name, on the default system."""
        scene, base_dir = load_scene(name)
        return cls.from_scene(scene, base_dir=base_dir)
