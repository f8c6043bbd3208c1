"""Collision checking against hand-computed contacts and clearances."""

from __future__ import annotations

import fcl
import numpy as np
import pytest
import trimesh
from scipy.spatial.transform import Rotation

from flycrane.model.cable_system import CableSystem
from flycrane.model.kinematics import (
    drone_positions_from_configuration,
    matrix_from_tilt_torsion,
    platform_points_from_configuration,
    tilt_torsion_from_matrix,
)
from flycrane.planning.problem import PlanningProblem
from flycrane.world.collision import CollisionChecker
from flycrane.world.contact import GROUND
from flycrane.world.scene import scene_from_dict

HOVER = [0.0, 0.0, 5.0, 0.0, 0.0, 0.0, 1.0, 1.0, 1.0]
BOUNDS = {"position_low": [-20, -20, 0], "position_high": [20, 20, 20]}


def checker(system: CableSystem, obstacles=(), payload=(), **extra) -> CollisionChecker:
    scene = scene_from_dict(
        {
            "obstacles": list(obstacles),
            "payload": {"shapes": list(payload)},
            "bounds": BOUNDS,
            "start": HOVER,
            "goal": HOVER,
            **extra,
        }
    )
    return CollisionChecker(system, scene)


def test_drone_sphere_clearance_to_a_box_face(system):
    drone3 = drone_positions_from_configuration(system, HOVER)[0, 2]  # on the -x side
    # A box whose +x face is 0.1 m beyond drone 3's sphere (radius 0.3).
    face = drone3[0] - 0.3 - 0.1
    box = {"kind": "box", "name": "wall", "center": [face - 0.5, 0, drone3[2]], "size": [1, 1, 1]}
    c = checker(system, [box])
    assert c.collision_free(HOVER)[0]
    assert c.clearance(HOVER) == pytest.approx(0.1, abs=1e-6)
    moved = np.array(HOVER)
    moved[0] -= 0.15  # now 0.05 m into the box
    contacts = c.contacts(moved)
    assert [(x.body, x.other) for x in contacts] == [("drone 3", "wall")]
    assert contacts[0].depth == pytest.approx(0.05, abs=1e-6)


@pytest.mark.parametrize(
    ("kind", "shape"),
    [
        ("box", {"size": [1, 1, 1]}),
        ("sphere", {"radius": 0.5}),
        ("cylinder", {"radius": 0.5, "height": 1.0}),
    ],
)
def test_obstacle_clearance_keeps_bodies_that_far_away(system, kind, shape):
    """Drone 3's sphere 0.1 m from an obstacle's face (x side): free without clearance and
    with 0.09 m, in collision with 0.11 m, and the clearance left is 0.1 - c."""
    drone3 = drone_positions_from_configuration(system, HOVER)[0, 2]
    face = drone3[0] - 0.3 - 0.1
    obstacle = {"kind": kind, "name": "post", "center": [face - 0.5, 0, drone3[2]], **shape}
    for clearance, free in ((0.0, True), (0.09, True), (0.11, False)):
        c = checker(system, [obstacle], collision={"obstacle_clearance": clearance})
        assert c.collision_free(HOVER)[0] == free, clearance
        if free:
            assert c.clearance(HOVER) == pytest.approx(0.1 - clearance, abs=1e-6)
        else:
            assert [x.other for x in c.contacts(HOVER)] == ["post"]


def test_obstacle_clearance_raises_the_ground(system):
    payload = [{"kind": "box", "name": "crate", "center": [0, 0, -0.3], "size": [0.4, 0.4, 0.2]}]
    c = checker(system, payload=payload, collision={"obstacle_clearance": 0.05})
    # crate bottom at z - 0.4: within 5 cm of the ground below z = 0.45
    assert not c.collision_free([0, 0, 0.44, 0, 0, 0, 1, 1, 1])[0]
    assert c.collision_free([0, 0, 0.46, 0, 0, 0, 1, 1, 1])[0]
    assert c.clearance([0, 0, 0.46, 0, 0, 0, 1, 1, 1]) == pytest.approx(0.01, abs=1e-9)


def test_a_mesh_obstacle_keeps_the_clearance_from_its_faces(system):
    """A horizontal sheet (two faces) just above the drones' spheres (0.3 m): they keep a
    0.05 m clearance from it exactly, as from a box's face."""
    hover = np.array(HOVER, dtype=float)
    top = drone_positions_from_configuration(system, hover)[0, :, 2].max() + 0.3
    sheet = {"kind": "mesh", "vertices": [[-5, -5, 0], [5, -5, 0], [5, 5, 0], [-5, 5, 0]],
             "faces": [[0, 1, 2], [0, 2, 3]]}  # fmt: skip
    for gap in (0.049, 0.051, 0.2):
        scene = scene_from_dict({
            "obstacles": [{**sheet, "center": [0.0, 0.0, float(top + gap)]}], "bounds": BOUNDS,
            "start": HOVER, "goal": HOVER, "collision": {"obstacle_clearance": 0.05}})  # fmt: skip
        c = CollisionChecker(system, scene)
        assert c.collision_free(hover)[0] == (gap > 0.05), gap
        assert c.clearance(hover) == pytest.approx(gap - 0.05, abs=1e-6)


def test_cable_crossing_a_thin_bar(system):
    # Cable 1 runs from B1 = (r, 0, 5) to drone 1; a thin bar across its middle hits it.
    r = 1.4 / np.sqrt(3)
    a = drone_positions_from_configuration(system, HOVER)[0, 0]
    middle = (np.array([r, 0, 5.0]) + a) / 2
    bar = {"kind": "box", "name": "bar", "center": list(middle), "size": [0.02, 0.02, 0.02]}
    hits = checker(system, [bar]).contacts(HOVER)
    assert {x.body for x in hits} == {"cable 1"} and hits[0].other == "bar"
    bar["center"] = list(middle + [0, 0, 0.05])  # 5 cm above: clear of the 1 cm cable
    assert checker(system, [bar]).collision_free(HOVER)[0]


def test_platform_and_payload_on_the_ground(system):
    payload = [{"kind": "box", "name": "crate", "center": [0, 0, -0.3], "size": [0.4, 0.4, 0.2]}]
    c = checker(system, payload=payload)
    # crate bottom at z - 0.4: touching the ground below z = 0.4, clear above
    assert c.collision_free([0, 0, 0.41, 0, 0, 0, 1, 1, 1])[0]
    assert c.clearance([0, 0, 0.41, 0, 0, 0, 1, 1, 1]) == pytest.approx(0.01, abs=1e-9)
    hits = c.contacts([0, 0, 0.38, 0, 0, 0, 1, 1, 1])
    assert [(x.body, x.other) for x in hits] == [("crate", "ground")]
    no_payload = checker(system)
    # 5 mm up: the 2 cm thick platform and the 1 cm cable ends at b_i all touch the ground.
    bodies = {x.body for x in no_payload.contacts([0, 0, 0.005, 0, 0, 0, 1, 1, 1])}
    assert bodies == {"platform"} | {f"cable {i}" for i in range(1, 7)}


def test_drone_separation_just_above_and_below_the_minimum(system):
    # At level hover, drones are sqrt(3) * (distance from P) apart; pick the minimum around it.
    drones = drone_positions_from_configuration(system, HOVER)[0]
    gap = np.linalg.norm(drones[0] - drones[1])
    for minimum, free in ((gap - 1e-6, True), (gap + 1e-6, False)):
        c = checker(system, collision={"min_drone_separation": minimum})
        assert c.collision_free(HOVER)[0] is np.True_ if free else not c.collision_free(HOVER)[0]
    hits = checker(system, collision={"min_drone_separation": gap + 0.01}).contacts(HOVER)
    assert {(x.body, x.other) for x in hits} == {
        ("drone 1", "drone 2"),
        ("drone 1", "drone 3"),
        ("drone 2", "drone 3"),
    }


def test_drone_against_another_drones_cable(system):
    # Drones 1 and 3 folded inward meet over vertex V3; with the separation check relaxed
    # drone 3's sphere still reaches cable 1 of drone 1. Depth by brute-force sampling.
    q = [0, 0, 5, 0, 0, 0, 1.7, 1.0, 2.0]
    b = platform_points_from_configuration(system, q)[0]
    a = drone_positions_from_configuration(system, q)[0]
    samples = b[0] + np.linspace(0, 1, 20001)[:, None] * (a[0] - b[0])
    gap = np.linalg.norm(samples - a[2], axis=1).min()
    hits = checker(system, collision={"min_drone_separation": 0.3}).contacts(q)
    cable = [x for x in hits if (x.body, x.other) == ("drone 3", "cable 1")]
    assert cable and cable[0].depth == pytest.approx(0.3 + 0.01 - gap, abs=1e-4)


def test_cable_against_payload_but_not_at_its_attachment(system):
    # A payload plate right under the platform touches the cables only at their anchors.
    plate = {"kind": "box", "name": "plate", "center": [0, 0, -0.06], "size": [1.5, 1.5, 0.1]}
    assert checker(system, payload=[plate]).collision_free(HOVER)[0]
    # A post sticking up through cable 1's path is a real contact.
    r = 1.4 / np.sqrt(3)
    a = drone_positions_from_configuration(system, HOVER)[0, 0]
    mid = (np.array([r, 0, 0.0]) + (a - [0, 0, 5.0])) / 2  # platform frame (P at origin)
    post = {"kind": "box", "name": "post", "center": list(mid), "size": [0.05, 0.05, 0.05]}
    hits = checker(system, payload=[post]).contacts(HOVER)
    assert ("cable 1", "post") in {(x.body, x.other) for x in hits}


def test_mesh_obstacle_from_an_stl_file(system, tmp_path):
    trimesh.creation.box(extents=[1, 1, 1]).export(tmp_path / "cube.stl")
    scene = scene_from_dict(
        {
            "obstacles": [
                {"kind": "mesh", "name": "cube", "file": "cube.stl", "center": [0, 0, 5]}
            ],
            "bounds": BOUNDS,
            "start": HOVER,
            "goal": HOVER,
        }
    )
    c = CollisionChecker(system, scene, tmp_path)
    assert next(x.other for x in c.contacts(HOVER)) == "cube"  # platform inside the cube
    assert c.collision_free([5, 5, 5, 0, 0, 0, 1, 1, 1])[0]


def test_batch_agrees_with_single_checks_and_first_collision(system):
    wall = {"kind": "box", "name": "wall", "center": [3, 0, 5], "size": [0.5, 10, 10]}
    c = checker(system, [wall])
    line = np.array(HOVER) + np.linspace(0, 1, 41)[:, None] * [4, 0, 0, 0, 0, 0, 0, 0, 0]
    batch = c.collision_free(line)
    single = np.array([c.collision_free(q)[0] for q in line])
    np.testing.assert_array_equal(batch, single)
    assert batch[0] and not batch[-1]
    assert c.first_collision(line) == int(np.argmin(batch))
    assert c.first_collision(line[:3]) is None


def _twisted(q: np.ndarray, twist: np.ndarray) -> np.ndarray:
    """q with its platform moved by a small twist (translation, rotation vector; world
    axes), its alphas kept."""
    moved = q.copy()
    moved[:3] += twist[:3]
    turned = Rotation.from_rotvec(twist[3:]).as_matrix() @ matrix_from_tilt_torsion(q[3:6])
    moved[3:6] = tilt_torsion_from_matrix(turned)
    return moved


@pytest.mark.parametrize("name", ["puzzle", "rescue", "site"])
def test_the_closest_pair_is_the_least_over_every_pair(name):
    """:meth:`closest` skips pairs by their boxes; fcl on every robot body against every
    obstacle (and the ground) finds nothing closer, on configurations of primitive scenes
    and a mesh scene. The gap's gradient (:meth:`gap_gradients`: from fcl's nearest points
    between primitives, by central differences with a mesh) is the central difference of
    :meth:`clearance` in a twist of the platform, where the closest pair is an
    obstacle's."""
    problem = PlanningProblem.named(name)
    checker = problem.validity.collision
    q = problem.space.sample_uniform(np.random.default_rng(2), 60)
    request = fcl.DistanceRequest(enable_signed_distance=True)
    for row in q:
        pose = checker._pose(row[None])
        centers, halves, kinds = checker._robot_boxes(pose)
        ground = checker.scene.ground
        every = [centers[0, b, 2] - halves[0, b, 2] - checker._ground_z for b in range(len(kinds))]
        every = every if ground else []
        every += [
            fcl.distance(checker._robot_object(kind, index, pose, 0), o.obstacle, request,
                         fcl.DistanceResult()) - o.margin
            for kind, index in kinds for o in checker.obstacles
        ]  # fmt: skip
        assert checker.closest(row).distance == pytest.approx(min(every), abs=1e-12)
    gaps, gradients = checker.gap_gradients(q)
    np.testing.assert_array_equal(gaps, [checker.clearance(row) for row in q])
    step, compared = 1e-5, 0
    for row, gradient in zip(q, gradients, strict=True):
        if checker.closest(row).other == GROUND or not checker.clearance(row) > 0:
            continue
        numeric = [
            (
                checker.clearance(_twisted(row, e * step))
                - checker.clearance(_twisted(row, -e * step))
            )
            / (2 * step)
            for e in np.eye(6)
        ]
        np.testing.assert_allclose(gradient, numeric, atol=2e-3)
        compared += 1
    assert compared >= 20


def test_the_gaps_of_many_configurations_are_bounded_a_few_rows_at_a_time(monkeypatch):
    """:meth:`gap_gradients` bounds its pairs a chunk of rows at a time (those arrays hold
    rows x bodies x obstacles numbers: gigabytes at once for a path among thousands of
    obstacles); in chunks of 7 rows each gap is still its row's own clearance, and the
    gradients those of one chunk."""
    checker = PlanningProblem.named("puzzle").validity.collision
    q = PlanningProblem.named("puzzle").space.sample_uniform(np.random.default_rng(5), 30)
    whole = checker.gap_gradients(q)
    bodies = len(checker._robot_boxes(checker._pose(q[:1]))[2])
    chunk = 7 * bodies * len(checker.obstacles)
    monkeypatch.setattr("flycrane.world.collision.PAIR_BOUNDS_SIZE", chunk)
    gaps, gradients = checker.gap_gradients(q)
    np.testing.assert_array_equal(gaps, [checker.clearance(row) for row in q])
    np.testing.assert_array_equal(gaps, whole[0])
    np.testing.assert_array_equal(gradients, whole[1])
