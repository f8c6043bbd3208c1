"""The FlyCrane and its scene as Foxglove scene entities (``foxglove.SceneUpdate``).

The platform, payload, cables and drones at one configuration, and the obstacles and ground
once; the MCAP logs of missions and flights (:mod:`missions.export.mission_mcap`) show them.
"""

from __future__ import annotations

import numpy as np
from foxglove_schemas_protobuf.SceneUpdate_pb2 import SceneUpdate
from scipy.spatial.transform import Rotation

from flycrane.model.cable_system import CABLE_DRONE
from flycrane.world.scene import Box, Cylinder, Mesh, SceneSpec, Sphere

GREY, ORANGE, BLUE, RED = (
    (0.6, 0.6, 0.6, 0.5),
    (1.0, 0.6, 0.1, 0.9),
    (0.2, 0.4, 1.0, 0.9),
    (0.9, 0.1, 0.1, 1.0),
)


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
    axes = rotation @ shape.axes
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


def crane_update(
    scene: SceneSpec,
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
    for shape in scene.payload.shapes:
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
        drone.size.x = drone.size.y = drone.size.z = 2 * scene.collision.drone_radius
        _set_color(drone.color, BLUE)
    return update


def scene_update(scene: SceneSpec, stamp: int) -> SceneUpdate:
    """The scene's obstacles and ground, in the world frame."""
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
