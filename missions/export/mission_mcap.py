"""An MCAP log of a mission that opens in Foxglove.

Foxglove's own message types are encoded with protobuf through the maintained
``foxglove-schemas-protobuf`` package (and ``mcap-protobuf-support`` for the schema
descriptors); our annotations are JSON with a JSON schema, which Foxglove plots as well.
Topics (log time = mission start + track time):

- ``/scene`` foxglove.SceneUpdate: obstacles and ground once, then the FlyCrane (platform,
  payload, cables, drones) at every sample of the dense track (decimated to ``rate`` Hz);
- ``/tf`` foxglove.FrameTransform ``world`` -> ``platform``;
- ``/drone{k}/fix`` foxglove.LocationFix per drone (WGS84 of the planned positions);
- ``/annotations/tensions``, ``/annotations/thrusts``, ``/annotations/cost`` at every
  waypoint (JSON);
- ``/mission/drone{k}`` the mission items per drone, once (JSON);
- any further JSON records the caller adds (a flight's figures, ``missions.flight_report``);
- metadata records ``system``, ``scene``, ``planner``, ``mission`` (JSON texts).
"""

from __future__ import annotations

import json
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from foxglove_schemas_protobuf.FrameTransform_pb2 import FrameTransform
from foxglove_schemas_protobuf.LocationFix_pb2 import LocationFix
from foxglove_schemas_protobuf.SceneUpdate_pb2 import SceneUpdate
from mcap.writer import Writer
from mcap_protobuf.schema import build_file_descriptor_set
from scipy.spatial.transform import Rotation

from flycrane.model.cable_system import CABLE_DRONE, CableSystem
from flycrane.model.kinematics import forward_kinematics, matrix_from_tilt_torsion
from flycrane.world.scene import Box, Cylinder, Mesh, SceneSpec, Sphere
from missions.export.formats import mission_json
from missions.export.items import DroneMission
from missions.geodesy import geodetic_from_enu
from missions.options import MissionOptions
from missions.trajectory.annotations import Annotations
from missions.trajectory.tracks import Track, samples_at_rate

GREY, ORANGE, BLUE, RED = (
    (0.6, 0.6, 0.6, 0.5),
    (1.0, 0.6, 0.1, 0.9),
    (0.2, 0.4, 1.0, 0.9),
    (0.9, 0.1, 0.1, 1.0),
)


@dataclass(frozen=True)
class LogInputs:
    """Everything the log shows."""

    system: CableSystem
    scene: SceneSpec
    track: Track
    annotations: Annotations | None  #: the waypoints' statics (None: a flown track)
    missions: Sequence[DroneMission]
    options: MissionOptions
    start_ns: int  #: log time of mission time 0 [ns since the Unix epoch]
    metadata: Mapping[str, Mapping[str, Any]]  #: name -> plain data (system, planner, ...)
    #: further JSON messages: (mission time [s], topic, body)
    records: Sequence[tuple[float, str, Mapping[str, Any]]] = ()


def _set_pose(pose, position, rotation=None) -> None:
    """Position and orientation; no ``rotation``: the identity, set explicitly (an unset
    proto3 pose reads as the quaternion (0, 0, 0, 0), which is no rotation at all for a
    reader that applies it), without a scipy call for each of the log's many world-frame
    bodies."""
    pose.position.x, pose.position.y, pose.position.z = map(float, position)
    x, y, z, w = (
        (0.0, 0.0, 0.0, 1.0) if rotation is None else Rotation.from_matrix(rotation).as_quat()
    )
    pose.orientation.x, pose.orientation.y, pose.orientation.z, pose.orientation.w = x, y, z, w


def _set_color(color, rgba) -> None:
    color.r, color.g, color.b, color.a = rgba


def _add_shape(entity, shape, position, rotation, rgba) -> None:
    """A scene shape placed at (position, rotation) of its parent frame."""
    center = position + rotation @ np.array(shape.center)
    axes = rotation @ matrix_from_tilt_torsion(np.array(shape.rotation))
    if isinstance(shape, Box):
        primitive = entity.cubes.add()
        primitive.size.x, primitive.size.y, primitive.size.z = shape.size
    elif isinstance(shape, Sphere):
        primitive = entity.spheres.add()
        primitive.size.x = primitive.size.y = primitive.size.z = 2 * shape.radius
    elif isinstance(shape, Cylinder):
        primitive = entity.cylinders.add()
        primitive.size.x = primitive.size.y = 2 * shape.radius
        primitive.size.z = shape.height
        primitive.bottom_scale = primitive.top_scale = 1.0
    else:  # Mesh: inline triangles only (file meshes are drawn by their bounding box)
        primitive = entity.triangles.add()
        if isinstance(shape, Mesh) and shape.vertices is not None and shape.faces is not None:
            for face in shape.faces:
                for index in face:
                    point = primitive.points.add()
                    point.x, point.y, point.z = shape.scale * np.array(shape.vertices[index])
    _set_pose(primitive.pose, center, axes)
    _set_color(primitive.color, rgba)


def _crane_update(
    inputs: LogInputs,
    q: np.ndarray,
    rotation: np.ndarray,
    b: np.ndarray,
    a: np.ndarray,
    stamp: int,
) -> SceneUpdate:
    """The FlyCrane at q: its rotation (3, 3), platform points b (6, 3), drones a (3, 3)."""
    update = SceneUpdate()
    entity = update.entities.add()
    entity.id, entity.frame_id = "flycrane", "world"
    entity.timestamp.FromNanoseconds(stamp)
    # Points in world coordinates, so an identity pose.
    platform = entity.triangles.add()
    _set_pose(platform.pose, np.zeros(3))
    for point_xyz in b[[0, 2, 4]]:
        point = platform.points.add()
        point.x, point.y, point.z = map(float, point_xyz)
    _set_color(platform.color, ORANGE)
    for shape in inputs.scene.payload.shapes:
        _add_shape(entity, shape, q[:3], rotation, ORANGE)
    cables = entity.lines.add()
    _set_pose(cables.pose, np.zeros(3))  # world points, as for the platform
    cables.type = 2  # LINE_LIST
    cables.thickness = 0.02
    for i in range(6):
        for point_xyz in (b[i], a[CABLE_DRONE[i]]):
            point = cables.points.add()
            point.x, point.y, point.z = map(float, point_xyz)
    _set_color(cables.color, RED)
    for k in range(3):
        drone = entity.spheres.add()
        _set_pose(drone.pose, a[k])
        drone.size.x = drone.size.y = drone.size.z = 2 * inputs.scene.collision.drone_radius
        _set_color(drone.color, BLUE)
    return update


def _static_update(scene: SceneSpec, stamp: int) -> SceneUpdate:
    update = SceneUpdate()
    entity = update.entities.add()
    entity.id, entity.frame_id = "scene", "world"
    entity.timestamp.FromNanoseconds(stamp)
    for shape in scene.obstacles:
        _add_shape(entity, shape, np.zeros(3), np.eye(3), GREY)
    if scene.ground:
        ground = Box(center=(0.0, 0.0, -0.005), size=(100.0, 100.0, 0.01))
        _add_shape(entity, ground, np.zeros(3), np.eye(3), (0.3, 0.5, 0.3, 0.3))
    return update


def write_mcap(path: str | Path, inputs: LogInputs, rate: float = 10.0) -> Path:
    """Write the log (module docstring); returns its path."""
    path = Path(path)
    track, start = inputs.track, inputs.start_ns
    samples = samples_at_rate(track.time, rate)
    messages: list[tuple[int, str, bytes]] = []
    stamp_of = lambda t: start + round(float(t) * 1e9)  # noqa: E731
    messages.append((start, "/scene", _static_update(inputs.scene, start).SerializeToString()))
    lat, lon, alt = geodetic_from_enu(track.drones[samples], inputs.options.origin)
    # The crane's geometry for all samples at once (scipy and numpy once, not per sample).
    shown = track.q[samples]
    poses = forward_kinematics(inputs.system, shown)
    rotations, points, drones = poses.rotation, poses.platform_points, poses.drones
    quaternions = Rotation.from_matrix(rotations).as_quat()
    for n, k in enumerate(samples):
        stamp, q = stamp_of(track.time[k]), track.q[k]
        crane = _crane_update(inputs, q, rotations[n], points[n], drones[n], stamp)
        messages.append((stamp, "/scene", crane.SerializeToString()))
        transform = FrameTransform(parent_frame_id="world", child_frame_id="platform")
        transform.timestamp.FromNanoseconds(stamp)
        translation = transform.translation
        translation.x, translation.y, translation.z = map(float, q[:3])
        x, y, z, w = quaternions[n]
        transform.rotation.x, transform.rotation.y, transform.rotation.z, transform.rotation.w = (
            x,
            y,
            z,
            w,
        )
        messages.append((stamp, "/tf", transform.SerializeToString()))
        for j in range(3):
            fix = LocationFix(
                frame_id=f"drone{j + 1}",
                latitude=float(lat[n, j]),
                longitude=float(lon[n, j]),
                altitude=float(alt[n, j]),
            )
            fix.timestamp.FromNanoseconds(stamp)
            messages.append((stamp, f"/drone{j + 1}/fix", fix.SerializeToString()))
    annotations = inputs.annotations.records() if inputs.annotations is not None else []
    for record in annotations:
        stamp = stamp_of(record["time"])
        tensions = {
            "time": record["time"],
            "waypoint": record["waypoint"],
            **{f"cable{c['cable']}": c for c in record["cables"]},
        }
        thrusts = {
            "time": record["time"],
            "waypoint": record["waypoint"],
            **{f"drone{d['drone']}": d for d in record["drones"]},
        }
        cost = {"time": record["time"], "waypoint": record["waypoint"], "cost": record["cost"]}
        for topic, body in (
            ("/annotations/tensions", tensions),
            ("/annotations/thrusts", thrusts),
            ("/annotations/cost", cost),
        ):
            messages.append((stamp, topic, json.dumps(body).encode()))
    for when, topic, extra in inputs.records:
        messages.append((stamp_of(when), topic, json.dumps(extra).encode()))
    for mission in inputs.missions:
        messages.append(
            (start, f"/mission/drone{mission.drone}", json.dumps(mission_json(mission)).encode())
        )
    messages.sort(key=lambda m: m[0])  # stable: same-time messages keep their order

    with path.open("wb") as stream:
        writer = Writer(stream)
        writer.start(profile="", library="flycrane")
        channels: dict[str, int] = {}
        for topic_type, topics in (
            (SceneUpdate, ["/scene"]),
            (FrameTransform, ["/tf"]),
            (LocationFix, [f"/drone{j}/fix" for j in (1, 2, 3)]),
        ):
            schema = writer.register_schema(
                topic_type.DESCRIPTOR.full_name,
                "protobuf",
                build_file_descriptor_set(topic_type).SerializeToString(),
            )
            for topic in topics:
                channels[topic] = writer.register_channel(topic, "protobuf", schema)
        json_schema = writer.register_schema(
            "flycrane.Record", "jsonschema", json.dumps({"type": "object"}).encode()
        )
        # Sorted: set order follows Python's per-process string hashing, and would number
        # the channels differently in every run (same inputs, different files).
        for topic in sorted({m[1] for m in messages} - channels.keys()):
            channels[topic] = writer.register_channel(topic, "json", json_schema)
        for sequence, (stamp, topic, data) in enumerate(messages):
            writer.add_message(channels[topic], stamp, data, stamp, sequence)
        for name, content in inputs.metadata.items():
            writer.add_metadata(name, {"json": json.dumps(content, default=str)})
        writer.finish()
    return path
