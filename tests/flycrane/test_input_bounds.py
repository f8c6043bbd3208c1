"""Geometry the collision checker cannot use is refused with its field, never ignored.

Issue 10, item 2: a mesh with a huge or non-finite vertex passed validation and its
triangles were never checked (the broad phase squares its box to infinity), so a task
planned through it.
"""

from __future__ import annotations

import math

import pytest

from flycrane.errors import InputError
from flycrane.model.system_spec import system_from_dict
from flycrane.world.collision import CollisionChecker
from flycrane.world.scene import Mesh, scene_from_dict

HOVER = [0.0, 0.0, 5.0, 0.0, 0.0, 0.0, 1.0, 1.0, 1.0]
BOUNDS = {"position_low": [-20, -20, 0], "position_high": [20, 20, 20]}


def triangle_through_the_platform(far: float) -> dict:
    """A triangle in the plane z = 5 (the platform's, at HOVER) around P, one corner at y=far."""
    return {
        "kind": "mesh",
        "name": "sheet",
        "vertices": [[-3.0, -3.0, 5.0], [3.0, -3.0, 5.0], [0.0, far, 5.0]],
        "faces": [[0, 1, 2]],
    }


def scene(**extra) -> dict:
    return {"bounds": BOUNDS, "start": HOVER, "goal": HOVER, **extra}


def test_a_modest_triangle_through_the_platform_is_a_collision(system):
    # The evidence that the geometry below goes through the platform at HOVER.
    checker = CollisionChecker(system, scene_from_dict(scene(obstacles=[
        triangle_through_the_platform(10.0)])))  # fmt: skip
    assert not checker.collision_free(HOVER)[0]
    assert any(c.other == "sheet" for c in checker.contacts(HOVER))


@pytest.mark.parametrize("far", [1e300, 1e20, math.inf, math.nan])
def test_a_mesh_obstacle_with_a_huge_or_non_finite_vertex_is_refused(far):
    with pytest.raises(InputError) as info:
        scene_from_dict(scene(obstacles=[triangle_through_the_platform(far)]))
    fields = [p.field for p in info.value.problems]
    assert any(f.startswith("obstacles[0].vertices[2]") for f in fields), fields


def test_a_payload_mesh_with_a_huge_vertex_is_refused():
    shape = {**triangle_through_the_platform(1e300), "center": [0, 0, -5.0]}
    with pytest.raises(InputError) as info:
        scene_from_dict(scene(payload={"shapes": [shape]}))
    assert any(p.field.startswith("payload.shapes[0].vertices") for p in info.value.problems)


def test_scaling_cannot_take_a_mesh_beyond_the_bound():
    with pytest.raises(InputError) as info:
        scene_from_dict(scene(obstacles=[{**triangle_through_the_platform(10.0), "scale": 1e4}]))
    assert "within 10000 m" in str(info.value)


def test_the_checker_refuses_a_body_it_cannot_use(system):
    """Even past validation (a scene built in code), an unusable body stops the checker."""
    valid = scene_from_dict(scene())
    for far in (math.nan, 1e300):
        broken = Mesh.model_construct(**{**triangle_through_the_platform(far), "scale": 1.0})
        unusable = valid.model_copy(update={"obstacles": (broken,)})
        with pytest.raises(InputError) as info:
            CollisionChecker(system, unusable)
        assert info.value.problems[0].field == "scene.obstacles[0]"
        assert "cannot use" in info.value.problems[0].reason


def test_a_mesh_without_area_is_refused(system):
    line = {"kind": "mesh", "vertices": [[0, 0, 5], [1, 0, 5], [2, 0, 5]], "faces": [[0, 1, 2]]}
    with pytest.raises(InputError) as info:
        CollisionChecker(system, scene_from_dict(scene(obstacles=[line])))
    assert "no triangle of positive area" in str(info.value)


@pytest.mark.parametrize(
    ("change", "field"),
    [
        ({"platform_mass": 1e308}, "platform_mass"),
        ({"com_offset": [math.inf, 0, 0]}, "com_offset[0]"),
        ({"geometry": {"kind": "octahedral", "side": 1e300}}, "geometry.side"),
        ({"max_thrust": True}, "max_thrust"),
        ({"perturbation": {"force": 1e-300}}, "perturbation.force"),
        ({"gravity": 1e300}, "gravity"),
    ],
)
def test_system_numbers_are_finite_bounded_and_numbers(change, field):
    with pytest.raises(InputError) as info:
        system_from_dict(change)
    assert [p.field for p in info.value.problems] == [field]
