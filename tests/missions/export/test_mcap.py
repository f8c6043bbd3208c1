"""The MCAP log, read back with the ``mcap`` library and decoded with Foxglove's protobuf types.

Geometry in the log is compared with values computed here: platform vertices of the
octahedral preset rotated with scipy's "ZYZ" (design.md s.3-4), cable lengths, and a
first-order WGS84 conversion for the drones' fixes.
"""

from __future__ import annotations

import itertools
import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from foxglove_schemas_protobuf.FrameTransform_pb2 import FrameTransform
from foxglove_schemas_protobuf.LocationFix_pb2 import LocationFix
from foxglove_schemas_protobuf.SceneUpdate_pb2 import SceneUpdate
from mcap.reader import make_reader
from scipy.spatial.transform import Rotation

from flycrane.world.scene import load_scene
from missions.export.builder import build_missions
from missions.export.formats import mission_from_json
from missions.export.mission_mcap import LogInputs, write_mcap
from missions.options import MissionOptions
from missions.trajectory.annotations import annotate
from tests.missions.helpers import approximate_geodetic

START_NS = 1_777_905_015_000_000_000  # 2026-05-04 14:30:15 UTC
RATE = 10.0
DRONE_TOPICS = [f"/drone{j}/fix" for j in (1, 2, 3)]
ANNOTATION_TOPICS = ["/annotations/tensions", "/annotations/thrusts", "/annotations/cost"]
MISSION_TOPICS = [f"/mission/drone{j}" for j in (1, 2, 3)]


@pytest.fixture(scope="module")
def timed_track(curved_track, curved_flight):
    """The dense plan on mission time, as the pipeline logs it."""
    return curved_flight.retimed(curved_track)


@pytest.fixture(scope="module")
def log(system, timed_track, curved_flight, tmp_path_factory):
    options = MissionOptions()
    missions = build_missions(curved_flight, options)
    inputs = LogInputs(
        system=system,
        scene=load_scene("rescue")[0],
        track=timed_track,
        annotations=annotate(system, curved_flight.time, curved_flight.q),
        missions=missions,
        options=options,
        start_ns=START_NS,
        metadata={"system": system.spec.model_dump(mode="json"), "planner": {"seed": 0}},
    )
    path = write_mcap(tmp_path_factory.mktemp("mcap") / "mission.mcap", inputs, rate=RATE)
    with path.open("rb") as stream:
        reader = make_reader(stream)
        summary = reader.get_summary()
        messages = [(schema, channel, message) for schema, channel, message in
                    reader.iter_messages(log_time_order=False)]  # fmt: skip
    with path.open("rb") as stream:
        metadata = {m.name: m.metadata for m in make_reader(stream).iter_metadata()}
    return {"summary": summary, "messages": messages, "metadata": metadata, "missions": missions}


def by_topic(log, topic):
    return [(m.log_time, m.data) for _, c, m in log["messages"] if c.topic == topic]


def decimated_samples(times, rate):
    """Brute force of "decimated to rate Hz": the first sample at or after every tick, and
    the last sample."""
    chosen = {len(times) - 1}
    i = 0
    while i / rate < times[-1]:
        chosen.add(next(k for k, t in enumerate(times) if t >= i / rate))
        i += 1
    return sorted(chosen)


def test_every_channel_has_its_schema(log):
    summary = log["summary"]
    schemas = {s.id: s for s in summary.schemas.values()}
    channels = {c.topic: c for c in summary.channels.values()}
    expected = {"/scene": "foxglove.SceneUpdate", "/tf": "foxglove.FrameTransform",
                **dict.fromkeys(DRONE_TOPICS, "foxglove.LocationFix"),
                **dict.fromkeys(ANNOTATION_TOPICS + MISSION_TOPICS, "flycrane.Record")}  # fmt: skip
    assert set(channels) == set(expected)
    for topic, schema_name in expected.items():
        schema = schemas[channels[topic].schema_id]
        assert schema.name == schema_name
        json_record = schema_name == "flycrane.Record"
        assert schema.encoding == ("jsonschema" if json_record else "protobuf")
        assert channels[topic].message_encoding == ("json" if json_record else "protobuf")
    assert set(log["metadata"]) == {"system", "planner"}
    assert json.loads(log["metadata"]["planner"]["json"]) == {"seed": 0}


def test_message_counts_follow_the_samples_and_the_waypoints(log, timed_track, curved_flight):
    samples = decimated_samples(list(timed_track.time), RATE)
    assert len(by_topic(log, "/tf")) == len(samples)
    assert len(by_topic(log, "/scene")) == len(samples) + 1  # the static scene first
    for topic in DRONE_TOPICS:
        assert len(by_topic(log, topic)) == len(samples)
    for topic in ANNOTATION_TOPICS:
        records = [json.loads(data) for _, data in by_topic(log, topic)]
        assert [r["waypoint"] for r in records] == list(range(len(curved_flight.time)))
        assert [r["time"] for r in records] == pytest.approx(list(curved_flight.time))
    for topic in MISSION_TOPICS:
        assert len(by_topic(log, topic)) == 1
    tf_times = np.array([t for t, _ in by_topic(log, "/tf")])
    expected = START_NS + np.round(timed_track.time[samples] * 1e9).astype(np.int64)
    np.testing.assert_array_equal(tf_times, expected)


def test_log_times_never_decrease_and_start_at_mission_start(log, timed_track):
    times = [m.log_time for _, _, m in log["messages"]]
    assert times[0] == START_NS
    assert all(a <= b for a, b in itertools.pairwise(times))
    assert times[-1] == START_NS + round(timed_track.duration * 1e9)
    assert all(m.publish_time == m.log_time for _, _, m in log["messages"])


def test_mission_messages_carry_the_missions(log):
    for mission, topic in zip(log["missions"], MISSION_TOPICS, strict=True):
        ((_, data),) = by_topic(log, topic)
        assert mission_from_json(json.loads(data)) == mission


def platform_vertices(q):
    """Octahedral preset (design.md s.4): V1 = (r, 0, 0), V2, V3 at 120 degrees, rotated."""
    r = 1.4 / np.sqrt(3)
    angles = np.radians([0, 120, 240])
    local = np.stack([r * np.cos(angles), r * np.sin(angles), np.zeros(3)], axis=1)
    phi, theta, sigma = q[3:6]
    rotation = Rotation.from_euler("ZYZ", [phi, theta, sigma - phi])
    return q[:3] + rotation.apply(local), rotation


def world_points(primitive):
    """A primitive's points in the world: its pose must be a proper rigid transform."""
    o = primitive.pose.orientation
    quaternion = np.array([o.x, o.y, o.z, o.w])
    assert np.linalg.norm(quaternion) == pytest.approx(1.0, abs=1e-9)
    p = primitive.pose.position
    points = np.array([[pt.x, pt.y, pt.z] for pt in primitive.points])
    return np.array([p.x, p.y, p.z]) + Rotation.from_quat(quaternion).apply(points)


@pytest.mark.parametrize("which", [0, 7, 33, -1])
def test_scene_and_transform_show_the_planned_configuration(log, timed_track, which):
    scenes = by_topic(log, "/scene")[1:]
    stamp, data = scenes[which]
    k = int(np.argmin(np.abs(timed_track.time - (stamp - START_NS) / 1e9)))
    assert abs(timed_track.time[k] - (stamp - START_NS) / 1e9) < 1e-9
    q = timed_track.q[k]
    update = SceneUpdate()
    update.ParseFromString(data)
    (entity,) = update.entities
    assert (entity.id, entity.frame_id) == ("flycrane", "world")
    assert entity.timestamp.ToNanoseconds() == stamp
    vertices, rotation = platform_vertices(q)
    platform = world_points(entity.triangles[0])
    np.testing.assert_allclose(platform, vertices, atol=1e-9)
    # six cables from the platform vertices (two per vertex) to the drones, 2 m each
    cables = world_points(entity.lines[0]).reshape(6, 2, 3)
    np.testing.assert_allclose(np.linalg.norm(cables[:, 1] - cables[:, 0], axis=1), 2.0, atol=1e-9)
    np.testing.assert_allclose(cables[:, 0], vertices[[0, 0, 1, 1, 2, 2]], atol=1e-9)
    drones = np.array([[s.pose.position.x, s.pose.position.y, s.pose.position.z]
                       for s in entity.spheres])  # fmt: skip
    np.testing.assert_allclose(drones, timed_track.drones[k], atol=1e-9)
    np.testing.assert_allclose(cables[:, 1], drones[[0, 1, 1, 2, 2, 0]], atol=1e-9)
    assert all(s.size.x == pytest.approx(0.6) for s in entity.spheres)
    # the footbridge of the Rescue scene hangs 0.35 m below P along the platform normal
    (bridge,) = entity.cubes
    centre = [bridge.pose.position.x, bridge.pose.position.y, bridge.pose.position.z]
    np.testing.assert_allclose(centre, q[:3] + rotation.apply([0, 0, -0.35]), atol=1e-9)
    assert [bridge.size.x, bridge.size.y, bridge.size.z] == pytest.approx([4.6, 0.8, 0.1])
    # the transform at the same instant
    transform = FrameTransform()
    transform.ParseFromString(dict(by_topic(log, "/tf"))[stamp])
    assert (transform.parent_frame_id, transform.child_frame_id) == ("world", "platform")
    t = transform.translation
    np.testing.assert_allclose([t.x, t.y, t.z], q[:3], atol=1e-12)
    o = transform.rotation
    got = Rotation.from_quat([o.x, o.y, o.z, o.w])
    assert (got.inv() * rotation).magnitude() < 1e-9


def test_static_scene_has_the_buildings_and_the_ground(log):
    stamp, data = by_topic(log, "/scene")[0]
    assert stamp == START_NS
    update = SceneUpdate()
    update.ParseFromString(data)
    (entity,) = update.entities
    assert entity.id == "scene"
    boxes = sorted(
        ([c.pose.position.x, c.pose.position.y, c.pose.position.z], [c.size.x, c.size.y, c.size.z])
        for c in entity.cubes
    )
    assert boxes[0] == ([-6.0, 0.0, 4.0], [8.0, 10.0, 8.0])  # west building
    assert boxes[-1] == ([6.0, 0.0, 4.0], [8.0, 10.0, 8.0])  # east building
    assert len(boxes) == 3  # and the ground slab


def test_drone_fixes_are_the_planned_positions_in_wgs84(log, timed_track):
    samples = decimated_samples(list(timed_track.time), RATE)
    for j, topic in enumerate(DRONE_TOPICS):
        fixes = []
        for _, data in by_topic(log, topic):
            fix = LocationFix()
            fix.ParseFromString(data)
            fixes.append((fix.latitude, fix.longitude, fix.altitude))
        lat, lon = approximate_geodetic(timed_track.drones[samples, j], MissionOptions().origin)
        fixes = np.array(fixes)
        np.testing.assert_allclose(fixes[:, 0], lat, atol=1e-9)
        np.testing.assert_allclose(fixes[:, 1], lon, atol=1e-9)
        np.testing.assert_allclose(fixes[:, 2], 488.0 + timed_track.drones[samples, j, 2],
                                   atol=1e-4)  # fmt: skip


WRITE_TINY_LOG = """
import sys
from flycrane.model.cable_system import CableSystem
from flycrane.world.scene import load_scene
from missions.trajectory.annotations import annotate
from missions.export.builder import build_missions
from missions.export.mission_mcap import LogInputs, write_mcap
from missions.options import MissionOptions
from missions.trajectory.tracks import Track
from missions.autopilots.spline import SpeedLimits
from tests.missions.helpers import hand_made_flight

plan = hand_made_flight([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0]],
                        [SpeedLimits(0.25, 2.5, 1.5), SpeedLimits(5.0, 0.2, 1.5)])
system, options = CableSystem.from_spec(), MissionOptions()
write_mcap(sys.argv[1], LogInputs(
    system, load_scene("rescue")[0], Track(plan.time, plan.q, plan.drones),
    annotate(system, plan.time, plan.q), build_missions(plan, options), options,
    START_NS, {"planner": {"seed": 0}}))
""".replace("START_NS", str(START_NS))


def test_the_same_inputs_give_the_same_log_bytes(tmp_path):
    """Python randomises string hashing per process: nothing in the file may depend on it."""
    root = Path(__file__).resolve().parents[3]
    logs = []
    for seed in ("1", "2"):
        path = tmp_path / f"log{seed}.mcap"
        env = {**os.environ, "PYTHONHASHSEED": seed, "PYTHONPATH": str(root)}
        subprocess.run([sys.executable, "-c", WRITE_TINY_LOG, str(path)], cwd=root, env=env,
                       check=True, timeout=120)  # fmt: skip
        logs.append(path.read_bytes())
    assert logs[0] == logs[1]
