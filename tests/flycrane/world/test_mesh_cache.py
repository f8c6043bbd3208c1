"""Mesh files read once per process, mesh hierarchies shared between a scene's checkers,
and the hierarchy of the compiled checks built a level at a time: their contracts, against
independent evidence (parses and builds counted, files changed on disk, the depth-first
build the level-wise one replaced)."""

from __future__ import annotations

import os

import numpy as np
import pytest
import trimesh

from flycrane.planning.problem import PlanningProblem
from flycrane.world import bodies, bvh, scene
from flycrane.world.memo import SharedCache
from flycrane.world.scene import Mesh, SceneError, load_scene

#: Two OBJ files of the same size: one triangle, a vertex moved.
OBJ = "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n"
OBJ_EDITED = "v 0 0 0\nv 2 0 0\nv 0 1 0\nf 1 2 3\n"


@pytest.fixture
def parses(monkeypatch) -> list[str]:
    """The files trimesh parses from now on (the caches emptied first)."""
    scene._mesh_files.clear()
    bodies._mesh_models.clear()
    seen: list[str] = []
    load = trimesh.load_mesh

    def counted(file, *args, **kwargs):
        seen.append(kwargs.get("file_type", ""))
        return load(file, *args, **kwargs)

    monkeypatch.setattr(trimesh, "load_mesh", counted)
    return seen


def _box_file(path, faces: int = 200) -> None:
    mesh = trimesh.creation.box(extents=[2.0, 3.0, 4.0])
    while len(mesh.faces) < faces:
        mesh = mesh.subdivide()
    mesh.export(path)


def test_a_mesh_file_is_parsed_once_and_its_arrays_are_read_only(tmp_path, parses):
    _box_file(tmp_path / "box.stl")
    shape = Mesh(file="box.stl")
    first = shape.triangles(tmp_path)
    again = shape.triangles(tmp_path)
    assert parses == ["stl"]
    direct = trimesh.load_mesh(tmp_path / "box.stl")  # the arrays are trimesh's own
    for a, b, reference in zip(first, again, (direct.vertices, direct.faces), strict=True):
        assert a.dtype == b.dtype and np.array_equal(a, b) and np.array_equal(a, reference)
        assert not a.flags.writeable and not b.flags.writeable
        with pytest.raises(ValueError, match="read-only"):
            a[0, 0] = 1
    # another scale of the same file: no parse, vertices scaled
    double = Mesh(file="box.stl", scale=2.0).triangles(tmp_path)
    assert len(parses) == 2  # the direct load above
    assert np.array_equal(double[0], 2.0 * first[0]) and np.array_equal(double[1], first[1])
    # inline meshes are read-only too
    inline = Mesh(vertices=((0, 0, 0), (1, 0, 0), (0, 1, 0)), faces=((0, 1, 2),))
    assert not any(a.flags.writeable for a in inline.triangles(None))


def test_a_mesh_file_changed_on_disk_is_read_again(tmp_path, parses):
    path = tmp_path / "tri.obj"
    path.write_text(OBJ)
    shape = Mesh(file="tri.obj")
    assert shape.triangles(tmp_path)[0][1, 0] == 1.0
    path.write_text(OBJ + "v 5 5 5\n")  # another size
    assert shape.triangles(tmp_path)[0][1, 0] == 1.0 and len(parses) == 2
    path.write_text(OBJ_EDITED)  # the same size as the first
    assert shape.triangles(tmp_path)[0][1, 0] == 2.0 and len(parses) == 3
    assert shape.triangles(tmp_path)[0][1, 0] == 2.0 and len(parses) == 3


def test_a_mesh_file_that_fails_is_not_cached(tmp_path, parses):
    path = tmp_path / "bad.obj"
    path.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 9\n")
    shape = Mesh(file="bad.obj")
    for _ in range(2):
        with pytest.raises(SceneError, match=r"mesh\.file: .*bad\.obj: .*out of bounds"):
            shape.triangles(tmp_path)
    assert len(parses) == 2
    path.write_text(OBJ)
    assert shape.triangles(tmp_path)[1].tolist() == [[0, 1, 2]]


def test_the_caches_are_bounded():
    cache: SharedCache[str] = SharedCache(size=10, size_of=len)
    cache.put("a", "AAAA")
    cache.put("b", "BBBB")
    assert cache.get("a") == "AAAA"  # now the most recently used
    cache.put("c", "CCCC")  # 12 > 10: the least recently used goes
    assert (cache.get("a"), cache.get("b"), cache.get("c")) == ("AAAA", None, "CCCC")
    cache.put("e", "E" * 11)  # larger than all it may hold: not kept
    assert cache.get("e") is None and len(cache) == 2


def test_checkers_at_other_clearances_share_a_mesh_and_its_hierarchy(tmp_path, parses, monkeypatch):
    _box_file(tmp_path / "east.stl", faces=2000)
    base, _ = load_scene("rescue")
    east = Mesh(name="east building", file="east.stl", center=(6.0, 0.0, 4.0))
    mesh_scene = base.model_copy(update={"obstacles": (base.obstacles[0], east)})
    builds: list[int] = []
    build = bodies._bvh

    def counted(vertices, faces):
        builds.append(len(faces))
        return build(vertices, faces)

    monkeypatch.setattr(bodies, "_bvh", counted)
    problem = PlanningProblem.from_scene(mesh_scene, base_dir=tmp_path)
    checkers = [problem.validity.with_clearance(c) for c in (0.0, 0.05, 0.2)]
    assert len(parses) == 1
    assert len([n for n in builds if n >= 2000]) == 1  # the platform's prism aside
    meshes = {id(c.collision.obstacles[1].geometry) for c in checkers}
    assert len(meshes) == 1
    # the answers are a fresh build's: caches emptied, the same configurations
    rng = np.random.default_rng(3)
    q = np.tile(np.array(base.goal), (400, 1))
    q[:, :3] = rng.uniform([-9.0, -5.0, 0.5], [9.0, 5.0, 12.0], (400, 3))
    q[:, 5] = rng.uniform(-np.pi, np.pi, 400)
    shared = [c.is_safe(q) for c in checkers]
    scene._mesh_files.clear()
    bodies._mesh_models.clear()
    fresh = PlanningProblem.from_scene(mesh_scene, base_dir=tmp_path).validity
    for c, answers in zip((0.0, 0.05, 0.2), shared, strict=True):
        alone = fresh.with_clearance(c)
        assert np.array_equal(alone.is_safe(q), answers)
        assert np.array_equal(alone.collision.collision_free(q[:50]), answers[:50])
    assert 0 < shared[2].sum() < shared[0].sum() < len(q)  # the clearance matters here


def _depth_first(low, high):
    """The hierarchy as :func:`flycrane.world.bvh.build_hierarchy` built it before it was
    built a level at a time: a node at a time, from a stack."""
    low, high = np.asarray(low, dtype=float).reshape(-1, 3), np.asarray(high, float).reshape(-1, 3)
    if not len(low):
        return np.zeros((0, 3)), np.zeros((0, 3)), *(np.zeros(0, dtype=np.int64),) * 3
    centres = (low + high) / 2
    nodes_low, nodes_high, first, count = [], [], [], []
    order = np.arange(len(low))

    def add(begin, end):
        members = order[begin:end]
        nodes_low.append(low[members].min(axis=0))
        nodes_high.append(high[members].max(axis=0))
        first.append(begin)
        count.append(end - begin)
        return len(first) - 1

    pending = [(add(0, len(low)), 0, len(low))]
    while pending:
        node, begin, end = pending.pop()
        if end - begin <= bvh.LEAF_SIZE:
            continue
        members = order[begin:end]
        axis = int(np.argmax(np.ptp(centres[members], axis=0)))
        order[begin:end] = members[np.argsort(centres[members, axis], kind="stable")]
        middle = (begin + end) // 2
        left = add(begin, middle)
        add(middle, end)
        first[node], count[node] = left, 0
        pending += [(left, begin, middle), (left + 1, middle, end)]
    return (
        np.array(nodes_low),
        np.array(nodes_high),
        np.array(first, dtype=np.int64),
        np.array(count, dtype=np.int64),
        order.astype(np.int64),
    )


@pytest.mark.parametrize("shapes", [0, 1, 4, 5, 8, 9, 13, 64, 257, 1000, 4097])
def test_the_hierarchy_is_the_depth_first_builds_to_the_bit(shapes):
    """Ties of centres (rounded, equal along an axis, boxes of no size) and bounds of both
    zeros (0.0 and -0.0, which numpy's smallest and largest choose between as they
    please) included."""
    rng = np.random.default_rng(shapes)
    for variant in range(4):
        low = rng.normal(size=(shapes, 3))
        if variant & 1:
            low = np.round(low, 1)  # ties, and -0.0 among them
        if variant & 2:
            low[:, 1] = 0.5
        high = low + (rng.random((shapes, 3)) if variant < 3 else 0.0)
        built = bvh.build_hierarchy(low, high).arrays()
        for mine, reference in zip(built, _depth_first(low, high), strict=True):
            assert mine.dtype == reference.dtype and mine.shape == reference.shape
            assert mine.tobytes() == reference.tobytes()


def test_no_cached_array_can_be_changed_in_place(tmp_path, parses):
    _box_file(tmp_path / "box.stl")
    vertices, faces = scene._mesh_file(tmp_path / "box.stl")
    _, low, high = bodies._mesh_model(vertices, faces, "field", "box")
    for array in (vertices, faces, low, high):
        with pytest.raises(ValueError, match="read-only"):
            array += 1
    assert os.path.getsize(tmp_path / "box.stl") > 0
