"""A task's numbers must be given as numbers: ``true`` or ``"60"`` is refused naming the
field, never read as 1 or 60 (flycrane.quantities). Found over HTTP and in task files,
where a time budget of ``true`` planned for one second."""

from __future__ import annotations

import pytest

from flycrane.errors import InputError
from missions.task.resolve import resolve_task
from missions.task.spec import task_from_dict


@pytest.mark.parametrize(
    ("task", "field"),
    [
        ({"planner": {"time_budget": True}}, "planner.time_budget"),
        ({"planner": {"time_budget": "60"}}, "planner.time_budget"),
        ({"planner": {"step": "0.1"}}, "planner.step"),
        ({"planner": {"improve_time": "5"}}, "planner.improve_time"),
        ({"planner": {"goal_bias": True}}, "planner.goal_bias"),
        ({"planner": {"polish": "yes"}}, "planner.polish"),
        ({"mission": {"max_acceleration": "0.25"}}, "mission.max_acceleration"),
        # a tilt outside the chart, named as given (it was q.theta, or q[0..4].theta)
        ({"goal": [0, 0, 8.45, 0, -1, 0, 1, 1, 1]}, "goal[4]"),
        ({"start": {"position": [0, 0, 0.45], "orientation": [0, -1, 1.57]}},
         "start.orientation[1]"),
        ({"mission": {"position_error": {"common_horizontal": "0.1", "common_vertical": 0.1,
                                         "relative_horizontal": 0.1,
                                         "relative_vertical": 0.1}}},
         "mission.position_error.common_horizontal"),
    ],
)  # fmt: skip
def test_a_number_must_be_a_number_and_in_range(task, field):
    with pytest.raises(InputError) as info:
        task_from_dict(task)
    assert field in [p.field for p in info.value.problems], info.value.problems


@pytest.mark.parametrize(
    ("change", "field"),
    [
        ({"bounds": {"max_tilt": True}}, "scene.bounds.max_tilt"),
        ({"bounds": {"alpha_low": "0.3"}}, "scene.bounds.alpha_low"),
        ({"collision": {"obstacle_clearance": "0.5"}}, "scene.collision.obstacle_clearance"),
        ({"ground": "yes"}, "scene.ground"),
    ],
)
def test_an_inline_scene_s_numbers_are_numbers(change, field):
    scene = {"start": [0, 0, 5, 0, 0, 0, 1, 1, 1], "goal": [1, 0, 5, 0, 0, 0, 1, 1, 1]}
    scene["bounds"] = {"position_low": [-5, -5, 0], "position_high": [5, 5, 10]}
    for key, value in change.items():
        scene[key] = {**scene.get(key, {}), **value} if isinstance(value, dict) else value
    with pytest.raises(InputError) as info:
        task_from_dict({"scene": scene})
    assert field in [p.field for p in info.value.problems], info.value.problems


def test_integers_stand_for_floats():
    task = task_from_dict({"planner": {"time_budget": 60, "improve_time": 0}})
    assert task.planner.time_budget == 60.0


@pytest.mark.parametrize("document", [[], 5, "rescue"])
def test_a_task_that_is_not_an_object_says_so(document):
    with pytest.raises(InputError) as info:
        task_from_dict(document)
    assert [p.field for p in info.value.problems] == ["task"]


def test_a_system_the_model_refuses_is_named_under_system():
    """A drone's edge through the centroid: refused by the model, not by the schema, and
    named by the system's own field, geometry."""
    task = task_from_dict({"system": {"geometry": {"kind": "octahedral", "side": 1e-9}}})
    with pytest.raises(InputError) as info:
        resolve_task(task)
    assert [p.field for p in info.value.problems] == ["system.geometry"]
