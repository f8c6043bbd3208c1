"""The bidirectional T-RRT (``bitrrt``): statistics over seeds, determinism per seed, valid
paths by the checker's own evidence, on the shipped scenes and users' scenes.

Each returned path is judged independently of the planner: every configuration and every
motion between consecutive ones by the validity checker (compiled, held to python-fcl by
tests/flycrane/test_collision_kernel.py), and its end points against the task's. The
statistics are counted in expansion attempts, which a seed fixes, never in seconds, which
the machine's load does.
"""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from pydantic import ValidationError

from flycrane.planning import bitrrt, bitrrt_kernel
from flycrane.planning.bitrrt import BiTRRT, BiTRRTConfig, MeshScene
from flycrane.planning.bitrrt_kernel import MARGIN
from flycrane.planning.planners import PlannerOptions, make_planner, plan
from flycrane.planning.problem import PlanningProblem
from flycrane.planning.result import PlannerStatus, TerminationCondition
from flycrane.scene import scene_from_dict

#: Generous: the runs below take well under a second to tens of seconds (BENCHMARKS.md);
#: the budget only bounds a machine under heavy load, it is not what is tested.
BUDGET = 300.0


def assert_valid_path(problem: PlanningProblem, path: np.ndarray) -> None:
    assert len(path) >= 2
    np.testing.assert_allclose(path[0], problem.start, atol=1e-9)
    np.testing.assert_allclose(path[-1], problem.goal, atol=1e-9)
    assert problem.validity.is_valid(path).all()
    for a, b in itertools.pairwise(path):
        assert problem.validity.motion_is_valid(a, b)


def solve(problem: PlanningProblem, seed: int, config: BiTRRTConfig | None = None):
    planner = BiTRRT(problem.space, problem.validity, config)
    return planner.solve(problem.start, problem.goal, TerminationCondition(BUDGET), seed)


@pytest.mark.parametrize("scene", ["rescue_broad", "puzzle", "corridor"])
def test_solves_every_seed_with_valid_paths(scene):
    problem = PlanningProblem.named(scene)
    for seed in range(5):
        result = solve(problem, seed)
        assert result.status is PlannerStatus.EXACT_SOLUTION, (scene, seed, result.reason)
        assert_valid_path(problem, result.path)


def test_broad_puzzle_statistics_over_seeds():
    """The Puzzle with its whole workspace as bounds (a user's scene, nothing tuned): every
    one of 20 seeds solved, in a median of at most 10,000 expansion attempts (measured:
    about 2,500; BENCHMARKS.md). T-RRT and the first bitrrt solved 0-2 of 5 in 30 s."""
    problem = PlanningProblem.named("puzzle_broad")
    attempts = []
    for seed in range(20):
        result = solve(problem, seed)
        assert result.status is PlannerStatus.EXACT_SOLUTION, (seed, result.reason)
        attempts.append(result.statistics.expansion_attempts)
    assert_valid_path(problem, result.path)
    assert np.median(attempts) <= 10_000, attempts


def test_design_first_puzzle_is_solved():
    """design.md's first Puzzle geometry (a 0.2 m slab, a 1.1 x 0.5 m hole, a 90 degree
    yaw of the upper bar): no planner of ours solved it in 60 s before this one."""
    problem = PlanningProblem.named("puzzle_first")
    result = solve(problem, 1)
    assert result.status is PlannerStatus.EXACT_SOLUTION, result.reason
    assert_valid_path(problem, result.path)
    # Through the hole: from above the slab to the goal below, with the long bar tilted.
    assert result.path[:, 4].max() > 0.2


def test_same_seed_same_path_whatever_the_batching(monkeypatch):
    """The loop returns to Python every BATCH attempts; the random stream and the trees
    must not depend on where those returns fall."""
    problem = PlanningProblem.named("puzzle")
    first = solve(problem, 3)
    assert first.status is PlannerStatus.EXACT_SOLUTION
    np.testing.assert_array_equal(solve(problem, 3).path, first.path)
    monkeypatch.setattr(bitrrt, "BATCH", 7)
    np.testing.assert_array_equal(solve(problem, 3).path, first.path)
    other = solve(problem, 4).path
    assert other.shape != first.path.shape or not np.array_equal(other, first.path)


def test_enlarging_the_trees_keeps_them(monkeypatch):
    """Arrays that start just above one attempt's margin are enlarged many times (the
    grid's chains index nodes across the copies): same seed, same path as without."""
    problem = PlanningProblem.named("puzzle_broad")
    expected = solve(problem, 3)
    assert expected.statistics.nodes > 2 * (MARGIN + 8)
    monkeypatch.setattr(bitrrt, "INITIAL_CAPACITY", MARGIN + 8)
    np.testing.assert_array_equal(solve(problem, 3).path, expected.path)


def test_invalid_start_is_a_status_with_the_reason():
    problem = PlanningProblem.named("rescue")
    start = problem.start.copy()
    start[6:] = 1.6  # a cable goes slack
    result = BiTRRT(problem.space, problem.validity).solve(
        start, problem.goal, TerminationCondition(5.0)
    )
    assert result.status is PlannerStatus.INVALID_START
    assert "slack" in result.reason or "cable" in result.reason


def test_selected_by_the_planner_options_and_smoothed():
    problem = PlanningProblem.named("rescue")
    options = PlannerOptions(algorithm="bitrrt", seed=1, time_budget=BUDGET)
    outcome = plan(problem.space, problem.validity, problem.start, problem.goal, options)
    assert outcome.result.statistics.planner == "bitrrt"
    assert_valid_path(problem, outcome.path)
    assert outcome.metrics is not None and np.isfinite(outcome.metrics.max_cost)


def test_trrt_only_options_are_refused_for_bitrrt():
    with pytest.raises(ValidationError, match="init_temperature"):
        PlannerOptions(algorithm="bitrrt", init_temperature=1.0)
    PlannerOptions(algorithm="trrt", init_temperature=1.0)  # T-RRT's own option


def test_config_shares_are_checked():
    with pytest.raises(Exception, match="local_share"):
        BiTRRTConfig(local_share=0.7, other_share=0.5)
    with pytest.raises(Exception, match="translate_share"):
        BiTRRTConfig(translate_share=0.9, rotate_share=0.2)


def test_mesh_scenes_are_refused_naming_the_alternative():
    problem = PlanningProblem.named("rescue")
    triangle = {"kind": "mesh", "vertices": [[9, 9, 0], [10, 9, 0], [9, 10, 1]],
                "faces": [[0, 1, 2]]}  # fmt: skip
    data = problem.scene.model_dump(mode="json")
    data["obstacles"] = [*data["obstacles"], triangle]
    meshed = PlanningProblem.from_scene(scene_from_dict(data))
    assert meshed.validity.has_meshes
    with pytest.raises(MeshScene, match="trrt"):
        BiTRRT(meshed.space, meshed.validity)
    with pytest.raises(MeshScene):
        make_planner(meshed.space, meshed.validity, PlannerOptions(algorithm="bitrrt"))
    # The default, T-RRT, checks meshes with fcl.
    assert make_planner(meshed.space, meshed.validity, PlannerOptions()).name == "trrt"


def test_the_kernels_parameter_indices_follow_the_params_fields():
    """The compiled loop reads its parameters by index (P_<FIELD>)."""
    for index, name in enumerate(bitrrt_kernel.Params.__dataclass_fields__):
        assert getattr(bitrrt_kernel, f"P_{name.upper()}") == index, name


def test_options_written_out_whole_read_back():
    """A task file (task.json) carries every option, T-RRT's at their defaults too."""
    options = PlannerOptions(algorithm="bitrrt", seed=4)
    assert PlannerOptions.model_validate_json(options.model_dump_json()) == options
