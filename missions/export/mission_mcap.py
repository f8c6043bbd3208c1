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

from foxglove_schemas_protobuf.FrameTransform_pb2 import FrameTransform
from foxglove_schemas_protobuf.LocationFix_pb2 import LocationFix
from foxglove_schemas_protobuf.SceneUpdate_pb2 import SceneUpdate
from mcap.writer import Writer
from mcap_protobuf.schema import build_file_descriptor_set
from scipy.spatial.transform import Rotation

from flycrane.model.cable_system import CableSystem
from flycrane.model.kinematics import forward_kinematics
from flycrane.world.scene import SceneSpec
from missions.export.formats import mission_json
from missions.export.foxglove_scene import crane_update, scene_update
from missions.export.items import DroneMission
from missions.geodesy import geodetic_from_enu
from missions.options import MissionOptions
from missions.trajectory.annotations import Annotations
from missions.trajectory.tracks import Track, samples_at_rate


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


def write_mcap(path: str | Path, inputs: LogInputs, rate: float = 10.0) -> Path:
    """Write the log (module docstring); returns its path."""
    path = Path(path)
    track, start = inputs.track, inputs.start_ns
    samples = samples_at_rate(track.time, rate)
    lat, lon, alt = geodetic_from_enu(track.drones[samples], inputs.options.origin)
    # The crane's geometry for all samples at once (scipy and numpy once, not per sample).
    shown = track.q[samples]
    poses = forward_kinematics(inputs.system, shown)
    rotations, points, drones = poses.rotation, poses.platform_points, poses.drones
    quaternions = Rotation.from_matrix(rotations).as_quat()
    messages: list[tuple[int, str, bytes]] = []
    stamp_of = lambda t: start + round(float(t) * 1e9)  # noqa: E731
    messages.append((start, "/scene", scene_update(inputs.scene, start).SerializeToString()))
    for n, k in enumerate(samples):
        stamp, q = stamp_of(track.time[k]), track.q[k]
        crane = crane_update(inputs.scene, q, rotations[n], points[n], drones[n], stamp)
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
