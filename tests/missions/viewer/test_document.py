"""The viewer's document against independent evidence: the stored tracks, the cable lengths,
force balance on the platform and on each drone, analytic shape orientations, and the
translation a shift of every flown drone must give the reconstructed platform."""

from __future__ import annotations

import json
import shutil

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from flycrane.model.system_spec import SystemSpec
from missions.task.pipeline import run_task
from missions.task.spec import task_from_dict
from missions.viewer import FLOWN_FILE, VIEW_FORMAT, ViewUnavailableError, view_document

G = 9.81
#: A short task in a scene with one shape of each kind, away from the path (plans in ~1 s).
SCENE = {
    "name": "shapes",
    "obstacles": [
        {"kind": "box", "name": "crate", "center": [6, 0, 1], "size": [1, 2, 2]},
        {
            "kind": "cylinder",
            "name": "mast",
            "center": [-6, 0, 2],
            "radius": 0.5,
            "height": 4,
            "rotation": [0, 0.3, 0],
        },
        {"kind": "sphere", "name": "balloon", "center": [0, 6, 5], "radius": 1.0},
        {
            "kind": "mesh",
            "name": "tent",
            "center": [0, -6, 0],
            "vertices": [[0, 0, 0], [2, 0, 0], [0, 2, 0], [0, 0, 2]],
            "faces": [[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]],
            "scale": 0.5,
        },
    ],
    "payload": {"shapes": [{"kind": "box", "center": [0, 0, -0.3], "size": [0.6, 0.6, 0.3]}]},
    "bounds": {"position_low": [-4, -4, 0], "position_high": [4, 4, 10]},
    "start": [0, 0, 3, 0, 0, 0, 1, 1, 1],
    "goal": [1, 0.5, 4, 0, 0, 0.5, 1, 1, 1],
}
TASK = task_from_dict(
    {
        "name": "shapes",
        "scene": SCENE,
        "planner": {"seed": 0, "time_budget": 30},
        # a mesh obstacle cannot be grown by a clearance: plan as if drones were exact
        "mission": {"position_error": "exact"},
    }
)
DEFAULTS = SystemSpec()  # design.md s.5: masses, limits


@pytest.fixture(scope="module")
def planned(tmp_path_factory):
    out = tmp_path_factory.mktemp("shapes")
    outcome = run_task(TASK, out)
    assert outcome.status == "done", outcome.reason
    tracks = json.loads((out / "tracks.json").read_text(encoding="utf-8"))
    return out, tracks, view_document(TASK, out)


def test_document_is_json_with_its_format_and_facts(planned):
    _, _, document = planned
    assert json.loads(json.dumps(document, allow_nan=False)) == document
    assert document["format"] == VIEW_FORMAT and document["title"] == "shapes"
    facts = {f["label"]: f["value"] for f in document["facts"]}
    assert facts["scene"] == "shapes" and "waypoints" in facts["mission"]
    assert document["flown"] is None and document["notes"] == []


def test_frames_contain_the_waypoints_of_tracks_json(planned):
    _, tracks, document = planned
    frames = document["planned"]
    at = frames["waypoint_frames"]
    np.testing.assert_allclose(np.array(frames["time"])[at], tracks["time"], atol=1e-6)
    np.testing.assert_allclose(np.array(frames["drones"])[at], tracks["drones_enu"], atol=2e-6)
    q = np.array(tracks["configurations"])
    np.testing.assert_allclose(np.array(frames["platform_position"])[at], q[:, :3], atol=2e-6)
    assert frames["time"] == sorted(frames["time"])


def test_cables_have_their_lengths_and_start_on_the_posed_platform(planned):
    _, _, document = planned
    frames = document["planned"]
    cables = np.array(frames["cables"])  # (F, 6, 2, 3): platform point, drone
    lengths = np.linalg.norm(cables[:, :, 1] - cables[:, :, 0], axis=-1)
    np.testing.assert_allclose(lengths, DEFAULTS.geometry.cable_length, atol=1e-5)
    # The platform pose (p, quaternion) applied to B'_i gives each cable's platform end.
    b_local = DEFAULTS.geometry.platform_points()
    rotation = Rotation.from_quat(frames["platform_quaternion"])
    p = np.array(frames["platform_position"])
    ends = p[:, None, :] + np.stack([rotation.apply(b) for b in b_local], axis=1)
    np.testing.assert_allclose(ends, cables[:, :, 0], atol=1e-5)
    # Each cable's other end is its drone (design.md s.4: drones 1, 2, 2, 3, 3, 1).
    drones = np.array(frames["drones"])
    np.testing.assert_allclose(cables[:, :, 1], drones[:, [0, 1, 1, 2, 2, 0]], atol=1e-9)
    assert document["crane"]["cable_drone"] == [1, 2, 2, 3, 3, 1]


def test_tensions_and_thrusts_balance_the_weights(planned):
    """Newton on the platform (sum f0_i u_i = m g z) and on each drone (T = M g z + its two
    cables' pull), from the document's cable end points alone."""
    _, _, document = planned
    frames = document["planned"]
    cables = np.array(frames["cables"])
    u = cables[:, :, 1] - cables[:, :, 0]
    u /= np.linalg.norm(u, axis=-1, keepdims=True)
    f0 = np.array(frames["tension"])
    pull = f0[..., None] * u  # (F, 6, 3), on the platform
    weight = np.array([0.0, 0.0, DEFAULTS.platform_mass * G])
    np.testing.assert_allclose(
        pull.sum(axis=1), np.broadcast_to(weight, pull[:, 0].shape), atol=1e-3
    )
    arms = cables[:, :, 0] - np.array(frames["platform_position"])[:, None, :]
    np.testing.assert_allclose(np.cross(arms, pull).sum(axis=1), 0.0, atol=1e-3)
    for k, (i, j) in enumerate(((0, 5), (1, 2), (3, 4))):
        thrust = DEFAULTS.drone_mass[k] * G * np.array([0, 0, 1.0]) + pull[:, i] + pull[:, j]
        np.testing.assert_allclose(
            np.linalg.norm(thrust, axis=-1), np.array(frames["thrust"])[:, k], atol=1e-3
        )
    low, high = np.array(frames["tension_low"]), np.array(frames["tension_high"])
    assert np.all(low <= f0) and np.all(f0 <= high)
    assert np.all(np.array(frames["thrust"]) <= np.array(frames["thrust_bound"]) + 1e-9)


def test_limits_are_the_systems(planned):
    _, _, document = planned
    values = {line["label"].split(" =")[0]: line["value"] for line in document["limits"]["tension"]}
    assert values == {"f_lo": 0.5, "f_hi": 30.0}
    assert [line["value"] for line in document["limits"]["thrust"]] == [25.0]


def test_scene_shapes_as_given(planned):
    _, _, document = planned
    box, cylinder, sphere, mesh = document["scene"]["obstacles"]
    assert (box["kind"], box["size"], box["center"]) == ("box", [1.0, 2.0, 2.0], [6.0, 0.0, 1.0])
    assert (cylinder["radius"], cylinder["height"]) == (0.5, 4.0)
    # rotation (phi, theta, sigma) = (0, 0.3, 0) is Ry(0.3): the axis tips towards +x.
    axis = Rotation.from_quat(cylinder["quaternion"]).apply([0.0, 0.0, 1.0])
    np.testing.assert_allclose(axis, [np.sin(0.3), 0.0, np.cos(0.3)], atol=1e-7)
    assert sphere["radius"] == 1.0 and sphere["quaternion"] == [0.0, 0.0, 0.0, 1.0]
    np.testing.assert_allclose(mesh["vertices"], 0.5 * np.array(SCENE["obstacles"][3]["vertices"]))
    assert mesh["faces"] == SCENE["obstacles"][3]["faces"]
    assert document["scene"]["ground"] is True
    payload = document["crane"]["payload"]
    assert [(s["kind"], s["size"]) for s in payload] == [("box", [0.6, 0.6, 0.3])]
    platform = np.array(document["crane"]["platform"]["vertices"])
    # A 1.4 m equilateral platform: its vertices lie 1.4 / sqrt(3) from P.
    np.testing.assert_allclose(
        np.hypot(platform[:, 0], platform[:, 1]), 1.4 / np.sqrt(3), atol=1e-6
    )


def test_frame_budget_keeps_the_waypoints(planned):
    out, tracks, _ = planned
    document = view_document(TASK, out, max_frames=4)
    frames = document["planned"]
    waypoints = len(tracks["time"])
    assert len(frames["time"]) <= 4 + 1 + waypoints
    np.testing.assert_allclose(
        np.array(frames["time"])[frames["waypoint_frames"]], tracks["time"], atol=1e-6
    )


def test_flown_drones_shifted_carry_the_platform_shifted(planned, tmp_path):
    """Moving all three drones by d moves the hanging load by d: the reconstruction of
    flown positions equal to the plan's plus d must be the planned platform plus d."""
    out, tracks, _ = planned
    shutil.copytree(out, tmp_path, dirs_exist_ok=True)
    shift = np.array([0.3, -0.2, 0.1])
    flown = {
        "source": "test",
        "time": tracks["time"],
        "drones_enu": (np.array(tracks["drones_enu"]) + shift).tolist(),
        "extra": "ignored",
    }
    (tmp_path / FLOWN_FILE).write_text(json.dumps(flown), encoding="utf-8")
    document = view_document(TASK, tmp_path)
    frames = document["flown"]
    assert frames["source"] == "test" and all(frames["converged"])
    assert frames["time"] == pytest.approx(tracks["time"], abs=1e-6)
    q = np.array(tracks["configurations"])
    np.testing.assert_allclose(frames["platform_position"], q[:, :3] + shift, atol=1e-5)
    at = document["planned"]["waypoint_frames"]
    planned_rotations = np.array(document["planned"]["platform_quaternion"])[at]
    np.testing.assert_allclose(
        Rotation.from_quat(frames["platform_quaternion"]).as_matrix(),
        Rotation.from_quat(planned_rotations).as_matrix(),
        atol=1e-5,
    )
    cables = np.array(frames["cables"])
    np.testing.assert_allclose(
        np.linalg.norm(cables[:, :, 1] - cables[:, :, 0], axis=-1), 2.0, atol=1e-5
    )
    assert any(f["label"] == "flown" for f in document["facts"])


def test_flown_drones_no_cables_can_join_leave_the_platform_out(planned, tmp_path):
    """Drones 3 times as far apart as the plan's: no pose meets the six 2 m cables there."""
    out, tracks, _ = planned
    shutil.copytree(out, tmp_path, dirs_exist_ok=True)
    drones = np.array(tracks["drones_enu"][:2])
    centroid = drones[1].mean(axis=0)
    drones[1] = centroid + 3.0 * (drones[1] - centroid)
    flown = {"source": "test", "time": [0.0, 1.0], "drones_enu": drones.tolist()}
    (tmp_path / FLOWN_FILE).write_text(json.dumps(flown), encoding="utf-8")
    frames = view_document(TASK, tmp_path)["flown"]
    assert frames["converged"] == [True, False]
    for key in ("platform_position", "platform_quaternion", "cables", "tension", "thrust"):
        assert frames[key][0] is not None and frames[key][1] is None, key
    np.testing.assert_allclose(frames["drones"], drones, atol=1e-6)


@pytest.mark.parametrize(
    ("flown", "reason"),
    [
        ("not json", "file"),
        ({"source": "x", "time": [0, 2, 1], "drones_enu": [[[0, 0, 5]] * 3] * 3}, "decrease"),
        ({"source": "x", "time": [0, 1], "drones_enu": [[[0, 0, 5]] * 3]}, "shape"),
        ({"time": [0, 1], "drones_enu": [[[0, 0, 5]] * 3] * 2}, "source"),
        ({"source": "x", "time": [0, 1], "drones_enu": [[[0, 0, 1e300]] * 3] * 2}, "within"),
    ],
)
def test_bad_flown_file_is_named_in_the_notes(planned, tmp_path, flown, reason):
    out, _, _ = planned
    shutil.copytree(out, tmp_path, dirs_exist_ok=True)
    text = flown if isinstance(flown, str) else json.dumps(flown)
    (tmp_path / FLOWN_FILE).write_text(text, encoding="utf-8")
    document = view_document(TASK, tmp_path)
    assert document["flown"] is None
    assert len(document["notes"]) == 1
    assert FLOWN_FILE in document["notes"][0] and reason in document["notes"][0]


def test_a_task_without_tracks_cannot_be_viewed(tmp_path):
    with pytest.raises(ViewUnavailableError, match=r"tracks\.json"):
        view_document(TASK, tmp_path)


def test_the_clearance_shown_is_the_plan_s(planned, tmp_path):
    """A plan keeps the position-error model's clearance where it is more than its scene's
    (0 here); the page said the scene's."""
    out, _, _ = planned
    shutil.copytree(out, tmp_path, dirs_exist_ok=True)
    summary = json.loads((tmp_path / "summary.json").read_text(encoding="utf-8"))
    summary["mission"]["obstacle_clearance"] = 0.08
    (tmp_path / "summary.json").write_text(json.dumps(summary), encoding="utf-8")
    facts = {f["label"]: f["value"] for f in view_document(TASK, tmp_path)["facts"]}
    assert facts["obstacle clearance"] == "0.08 m"
