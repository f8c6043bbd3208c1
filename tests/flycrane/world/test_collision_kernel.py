"""The compiled collision path against python-fcl, the reference, on thousands of
configurations per scene.

Tolerance: the kernel must never call a configuration free where fcl finds a contact
(no tolerance at all: its decisions come from proven distance bounds), and may call one in
contact where fcl finds it free only within CONTACT_SLACK of touching, measured by fcl's
own clearance. (Within a few micrometres fcl disagrees with itself: its distance query
reports overlap, -1, for cylinders its collision query calls free, and its GJK distances
are accurate to its 1e-6 tolerance.) Configurations come uniform from the scene's bounds
and, to test the boundary where the two could disagree, bisected to within 1e-6 of contact
along motions from a free configuration to a colliding one.
"""

from __future__ import annotations

import numpy as np
import pytest

from flycrane.planning.problem import PlanningProblem
from flycrane.world.collision_kernel import CompiledScene, collision_free
from flycrane.world.scene import scene_from_dict

#: Largest fcl clearance [m] at which the kernel may still report a contact (module
#: docstring); measured: 2.2e-6 at most on these scenes.
CONTACT_SLACK = 1e-5

PRIMITIVES = {
    "name": "primitives",
    "obstacles": [
        {"kind": "box", "center": [2, 0, 3], "size": [1.5, 3, 0.4], "rotation": [0.3, 0.5, 1.0]},
        {
            "kind": "cylinder",
            "center": [-2, 1, 4],
            "radius": 0.6,
            "height": 3,
            "rotation": [1, 0.7, 0],
        },
        {"kind": "sphere", "center": [0, -2.5, 3.5], "radius": 0.9},
        {"kind": "box", "center": [0, 3, 6], "size": [6, 0.3, 0.3]},
    ],
    "payload": {
        "shapes": [
            {
                "kind": "box",
                "center": [0, 0, -0.5],
                "size": [1.2, 0.3, 0.2],
                "rotation": [0, 0.2, 0.4],
            },
            {"kind": "cylinder", "center": [0.2, 0, -0.9], "radius": 0.15, "height": 0.8},
            {"kind": "sphere", "center": [-0.3, 0.2, -1.2], "radius": 0.25},
        ]
    },
    "collision": {"obstacle_clearance": 0.02},
    "bounds": {"position_low": [-3, -3, 0.5], "position_high": [3, 3, 6], "max_tilt": 1.0},
    "start": [0, 0, 5, 0, 0, 0, 1, 1, 1],
    "goal": [0, 0, 5, 0, 0, 0, 1, 1, 1],
}


def box_mesh(center, size, rotation=(0.0, 0.0, 0.0)) -> dict:
    """A box as a triangle mesh (12 faces, outward)."""
    x, y, z = (s / 2 for s in size)
    vertices = [[sx * x, sy * y, sz * z] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)]
    faces = [[0, 1, 3], [0, 3, 2], [4, 6, 7], [4, 7, 5], [0, 4, 5], [0, 5, 1],
             [2, 3, 7], [2, 7, 6], [0, 2, 6], [0, 6, 4], [1, 5, 7], [1, 7, 3]]  # fmt: skip
    return {"kind": "mesh", "center": list(center), "rotation": list(rotation),
            "vertices": vertices, "faces": faces}  # fmt: skip


#: Obstacles given as triangle meshes, kept at a clearance: closed boxes, an open sheet
#: (two faces), an octahedron.
MESHES = {
    **PRIMITIVES,
    "name": "meshes",
    "obstacles": [
        box_mesh([2, 0, 3], [1.5, 3, 0.4], [0.3, 0.5, 1.0]),
        {
            "kind": "mesh",
            "vertices": [[-3, 0, 3], [-1, 2, 4], [-1, 0, 5], [-3, 2, 2]],
            "faces": [[0, 1, 2], [0, 3, 1]],
        },
        {
            "kind": "mesh",
            "center": [0, -2.5, 3.5],
            "vertices": [[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]],
            "faces": [
                [0, 2, 4],
                [2, 1, 4],
                [1, 3, 4],
                [3, 0, 4],
                [2, 0, 5],
                [1, 2, 5],
                [3, 1, 5],
                [0, 3, 5],
            ],
        },
        box_mesh([0, 3, 6], [6, 0.3, 0.3]),
    ],
    "collision": {"obstacle_clearance": 0.05},
}


def problem(name: str) -> PlanningProblem:
    if name in ("primitives", "meshes"):
        return PlanningProblem.from_scene(scene_from_dict({"primitives": PRIMITIVES,
                                                           "meshes": MESHES}[name]))  # fmt: skip
    return PlanningProblem.named(name)


def boundary_configurations(
    prob: PlanningProblem, free: np.ndarray, hit: np.ndarray, rng: np.random.Generator
) -> np.ndarray:
    """Configurations within ~1e-6 (path fraction) of contact: bisect fcl's verdict on
    local paths from free to colliding configurations, then keep both sides."""
    pairs = min(len(free), len(hit), 600)
    a, b = free[rng.permutation(len(free))[:pairs]], hit[rng.permutation(len(hit))[:pairs]]
    low, high = np.zeros(pairs), np.ones(pairs)
    for _ in range(20):
        middle = (low + high) / 2
        ok = prob.validity.collision.collision_free(prob.space.interpolate(a, b, middle))
        low, high = np.where(ok, middle, low), np.where(ok, high, middle)
    return np.concatenate([prob.space.interpolate(a, b, low), prob.space.interpolate(a, b, high)])


@pytest.mark.parametrize("name", ["rescue", "puzzle", "primitives", "meshes"])
def test_kernel_agrees_with_fcl(name):
    prob = problem(name)
    compiled = CompiledScene.build(prob.system, prob.scene)
    rng = np.random.default_rng(11)
    uniform = prob.space.sample_uniform(rng, 2000)
    reference = prob.validity.collision.collision_free(uniform)
    # both verdicts must be well represented for the comparison to mean anything
    assert 0.1 < reference.mean() < 0.9
    near = boundary_configurations(prob, uniform[reference], uniform[~reference], rng)
    q = np.concatenate([uniform, near])
    reference = np.concatenate([reference, prob.validity.collision.collision_free(near)])
    fast = collision_free(prob.system, compiled, q)
    false_free = np.flatnonzero(fast & ~reference)
    assert len(false_free) == 0, [
        [str(c) for c in prob.validity.collision.contacts(q[i])] for i in false_free[:3]
    ]
    false_contact = np.flatnonzero(~fast & reference)
    slack = [prob.validity.collision.clearance(q[i]) for i in false_contact]
    assert max(slack, default=0.0) <= CONTACT_SLACK
    # and the boundary set really is at the boundary, on both sides
    assert 0.3 < reference[len(uniform) :].mean() < 0.7


def test_each_self_rule_matches_fcl():
    """Hand-placed configurations breaking one rule each (fcl's contacts named), checked by
    both checkers."""
    prob = problem("primitives")
    compiled = CompiledScene.build(prob.system, prob.scene)
    hover = np.array([0, 0, 5, 0, 0, 0, 1, 1, 1.0])
    cases = {
        "drone 1 hits drone 2": np.r_[hover[:6], 1.75, 1.75, 1.75],
        "cable 6 hits payload box 1": np.r_[hover[:6], -2.5, 1.0, 1.0],
        "cable 1 hits payload cylinder 2": np.r_[hover[:6], -1.75, 1.0, 1.0],
        "cable 4 hits payload sphere 3": np.r_[hover[:6], 1.0, 1.0, -1.5],
        "drone 1 hits payload sphere 3": np.r_[hover[:6], -2.0, 1.0, 1.0],
        "payload sphere 3 hits ground": np.r_[0, 0, 1.2, hover[3:]],
    }
    assert collision_free(prob.system, compiled, hover[None])[0]
    for contact, q in cases.items():
        assert contact in [str(c).split(" (")[0] for c in prob.validity.collision.contacts(q)]
        assert not collision_free(prob.system, compiled, q[None])[0], contact
