"""Scenes: files by name and path, field-named errors, benchmark validity and difficulty."""

from __future__ import annotations

import itertools
import json

import numpy as np
import pytest

from flycrane.planning.problem import PlanningProblem
from flycrane.planning.validity import InvalidConfigurationError
from flycrane.world.scene import (
    MAX_OBSTACLES,
    SceneError,
    list_scenes,
    load_scene,
    scene_from_dict,
)

HOVER = [0.0, 0.0, 5.0, 0.0, 0.0, 0.0, 1.0, 1.0, 1.0]
BOUNDS = {"position_low": [-20, -20, 0], "position_high": [20, 20, 20]}


@pytest.fixture(scope="module", params=["rescue", "puzzle"])
def benchmark(request) -> PlanningProblem:
    return PlanningProblem.named(request.param)


def test_shipped_scenes_load_by_name_and_by_path():
    assert {"rescue", "puzzle"} <= set(list_scenes())
    scene, base = load_scene("rescue")
    again, _ = load_scene(base / "rescue.toml")
    assert scene == again and scene.payload.shapes[0].name == "footbridge"


def test_a_scene_file_in_json_loads_as_its_toml_does(tmp_path):
    """The service's scene presets are JSON: saved to a file, a user's task names it."""
    scene, _ = load_scene("rescue")
    path = tmp_path / "rescue_copy.json"
    path.write_text(json.dumps(scene.model_dump(mode="json")), encoding="utf-8")
    assert load_scene(path)[0] == scene
    path.write_text('{"name": "x",', encoding="utf-8")
    with pytest.raises(SceneError, match=r"file: not valid JSON: Expecting property name"):
        load_scene(path)


def test_a_scene_of_more_obstacles_than_a_checker_can_hold_is_refused():
    scene = load_scene("rescue")[0].model_dump(mode="json")
    box = {"kind": "box", "center": [-9000.0, -9000.0, 1.0], "size": [1.0, 1.0, 1.0]}
    scene["obstacles"] = [box] * (MAX_OBSTACLES + 1)
    with pytest.raises(SceneError, match=rf"obstacles: .*at most {MAX_OBSTACLES} items"):
        scene_from_dict(scene)


def test_puzzle_payload_changes_the_system():
    scene, _ = load_scene("puzzle")
    assert scene.system_spec().com_offset == (0.0, 0.0, -0.25)
    assert scene.system_spec().platform_mass == 1.5


@pytest.mark.parametrize(
    ("change", "field", "reason"),
    [
        (
            {"obstacles": [{"kind": "sphere", "radius": -1}]},
            "obstacles[0].radius",
            "greater than 0",
        ),
        ({"obstacles": [{"kind": "cone", "radius": 1}]}, "obstacles[0]", "kind"),
        ({"start": [0, 0, 5]}, "start", ""),
        ({"goal": [0, 0, 5, 0, -1, 0, 1, 1, 1]}, "goal[4]", "greater than or equal to 0"),
        ({"bounds": {"position_low": [0, 0, 0], "position_high": [1, -1, 1]}}, "bounds", "y"),
        (
            {"obstacles": [{"kind": "mesh", "vertices": [[0, 0, 0]], "faces": [[0, 1, 2]]}]},
            "obstacles[0]",
            "faces index",
        ),
        ({"payload": {"mass": 0}}, "payload.mass", "greater than 0"),
        ({"colour": "red"}, "colour", "not permitted"),
    ],
)
def test_bad_scenes_name_the_field(change, field, reason):
    data = {"bounds": BOUNDS, "start": HOVER, "goal": HOVER, **change}
    with pytest.raises(SceneError) as info:
        scene_from_dict(data)
    fields = [p.field for p in info.value.problems]
    assert any(f.startswith(field) for f in fields), fields
    assert reason in str(info.value)


def test_missing_scene_and_missing_mesh_file(tmp_path):
    with pytest.raises(SceneError, match="no scene 'atlantis'"):
        load_scene("atlantis")
    scene = scene_from_dict(
        {
            "obstacles": [{"kind": "mesh", "file": "nowhere.stl"}],
            "bounds": BOUNDS,
            "start": HOVER,
            "goal": HOVER,
        }
    )
    with pytest.raises(SceneError, match=r"mesh\.file"):
        PlanningProblem.from_scene(scene, base_dir=tmp_path)


def test_unreadable_scene_and_mesh_files_name_the_field(tmp_path):
    (tmp_path / "bad.toml").write_bytes(b"\xff\xfe")
    with pytest.raises(SceneError, match=r"file: not UTF-8 text") as info:
        load_scene(tmp_path / "bad.toml")
    assert info.value.source == str(tmp_path / "bad.toml")
    with pytest.raises(SceneError, match="file: not a regular file"):
        load_scene("/dev/zero")
    # a face naming a vertex the file does not have (trimesh's reader raises IndexError)
    (tmp_path / "bad.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 9\n")
    (tmp_path / "zero.obj").symlink_to("/dev/zero")
    for name, reason in (("bad.obj", "out of bounds"), ("zero.obj", "not a regular file")):
        scene = scene_from_dict(
            {
                "obstacles": [{"kind": "mesh", "file": name}],
                "bounds": BOUNDS,
                "start": HOVER,
                "goal": HOVER,
            }
        )
        with pytest.raises(SceneError, match=rf"mesh\.file: .*{name}: .*{reason}"):
            PlanningProblem.from_scene(scene, base_dir=tmp_path)


def test_benchmark_start_and_goal_are_valid(benchmark):
    validity = benchmark.validity
    assert validity.is_valid(np.stack([benchmark.start, benchmark.goal])).all()
    validity.require_valid(benchmark.start, "start")


def test_benchmark_straight_line_is_invalid(benchmark):
    assert not benchmark.validity.motion_is_valid(benchmark.start, benchmark.goal)
    line = benchmark.space.interpolate(benchmark.start, benchmark.goal, np.linspace(0, 1, 201))
    first = benchmark.validity.collision.first_collision(line)
    contacts = benchmark.validity.collision.contacts(line[first])
    payload = {s.name for s in benchmark.scene.payload.shapes}
    obstacles = {o.name for o in benchmark.scene.obstacles}
    # the payload is what hits the buildings / the slab on the way
    assert any(c.body in payload and c.other in obstacles for c in contacts), contacts


def test_invalid_start_error_names_constraints_and_bodies():
    problem = PlanningProblem.named("rescue")
    sunk = problem.start.copy()
    sunk[2] = 0.3  # bridge 10 cm into the ground
    slack = problem.start.copy()
    slack[6:] = 1.45
    with pytest.raises(InvalidConfigurationError) as info:
        problem.validity.require_valid(sunk, "start")
    assert "footbridge hits ground" in str(info.value) and info.value.what == "start"
    reason = problem.validity.explain(slack)
    assert reason.violations and not reason.contacts
    assert "cable 1: lowest tension" in str(reason)
    outside = problem.start.copy()
    outside[0] = 30.0
    assert "x = 30 not in [-12, 12]" in str(problem.validity.explain(outside))


def test_puzzle_witness_path_is_valid():
    """A path exists: the stored witness (a grid search, not our planners) threads the long
    bar at a tilt and passes the validity checker at the planner's motion resolution."""
    import json

    from flycrane.world.scene import SCENES_DIR

    problem = PlanningProblem.named("puzzle")
    path = np.array(json.loads((SCENES_DIR / "puzzle_witness.json").read_text())["path"])
    np.testing.assert_allclose(path[0], problem.start, atol=1e-12)
    np.testing.assert_allclose(path[-1], problem.goal, atol=1e-12)
    assert all(problem.validity.motion_is_valid(a, b) for a, b in itertools.pairwise(path))
    assert path[:, 4].max() > 0.1


def _puzzle_shape(scene, name: str):
    return next(shape for shape in scene.payload.shapes if shape.name == name)


def _puzzle_hole(scene) -> tuple[float, float]:
    """The hole's (x, y) size, from the four slab boxes whose outer edges are at +-6 m."""
    slab = {o.name: o for o in scene.obstacles}
    east, north = slab["slab east"], slab["slab north"]
    return east.center[0] * 2 - east.size[0], north.center[1] * 2 - north.size[1]


def test_puzzle_long_bar_is_longer_than_the_hole_diagonal():
    """The character design.md asks the calibration to keep, read from the scene file."""
    scene, _ = load_scene("puzzle")
    long_bar = _puzzle_shape(scene, "long bar").size[0]
    hole_x, hole_y = _puzzle_hole(scene)
    assert long_bar > np.hypot(hole_x, hole_y)
    assert _puzzle_shape(scene, "short bar").size[1] < hole_y  # passes without a yaw


def test_puzzle_has_no_level_passage():
    """With zero tilt the long bar is horizontal; to get below the slab it must, at some
    moment, lie at the slab's mid-height. There every position over the hole and every
    heading collides with the real slab (brute force, no clearance), so no path exists
    without tilt."""
    problem = PlanningProblem.named("puzzle")
    slab_middle = next(o for o in problem.scene.obstacles if o.name == "slab west").center[2]
    hole_x, hole_y = _puzzle_hole(problem.scene)
    bar_below_p = -_puzzle_shape(problem.scene, "long bar").center[2]
    x, y, sigma = np.meshgrid(
        np.linspace(-hole_x / 2, hole_x / 2, 19),
        np.linspace(-hole_y / 2, hole_y / 2, 13),
        np.linspace(0, np.pi, 90, endpoint=False),
        indexing="ij",
    )
    q = np.zeros((x.size, 9))
    q[:, 0], q[:, 1], q[:, 5] = x.ravel(), y.ravel(), sigma.ravel()
    q[:, 2] = slab_middle + bar_below_p
    q[:, 6:] = 1.0
    real = problem.validity.with_clearance(0.0).collision
    assert not real.collision_free(q).any()


def test_puzzle_is_not_solved_without_tilt():
    from flycrane.planning.planners import PlannerOptions, plan

    problem = PlanningProblem.named("puzzle")
    level = problem.scene.model_copy(
        update={"bounds": problem.scene.bounds.model_copy(update={"max_tilt": 1e-9})}
    )
    flat = PlanningProblem.from_scene(level)
    outcome = plan(
        flat.space, flat.validity, flat.start, flat.goal, PlannerOptions(time_budget=10.0, seed=1)
    )
    assert not outcome.result.status.solved
