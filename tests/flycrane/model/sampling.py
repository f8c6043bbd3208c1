"""Configurations the model's tests are held on."""

from __future__ import annotations

import numpy as np

from flycrane.model.cable_system import CableSystem
from flycrane.model.statics import evaluate_statics
from flycrane.planning.problem import PlanningProblem


def feasible_configurations(scene: str, seed: int, count: int) -> tuple[CableSystem, np.ndarray]:
    """The scene's system and ``count`` feasible configurations (taut cables, non-singular
    J) drawn uniformly from its space, of 400 tries."""
    problem = PlanningProblem.named(scene)
    q = problem.space.sample_uniform(np.random.default_rng(seed), 400)
    return problem.system, q[evaluate_statics(problem.system, q).feasible][:count]
