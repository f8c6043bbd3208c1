"""Collision checking of FlyCrane configurations with python-fcl (design.md section 6).

Robot bodies: the platform (thin prism), the payload shapes, the six cables (capsules from
b_i to A_i) and the three drones (spheres at A_k). They are checked against the scene's
obstacles and the ground (z = 0), and against each other: drone centres at least the
minimum separation apart, no drone touching another drone's cables, no cable or drone
touching the payload. A cable starts on the platform, so its first
``cable_clearance_at_platform`` metres are not checked against the payload (they touch it
wherever the payload is attached at b_i).

How: for a batch of configurations, numpy computes world boxes of every body and keeps only
the (configuration, body, obstacle) triples whose boxes overlap; fcl decides those exactly.
Sphere-sphere and sphere-capsule self-checks are closed-form in numpy. In open space a
configuration therefore costs a few vectorized operations and no fcl call at all.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import fcl
import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.spatial.transform import Rotation

from flycrane.model.cable_system import CABLE_DRONE, CableSystem
from flycrane.model.kinematics import (
    as_configurations,
    drone_positions_in_platform_frame,
    matrix_from_tilt_torsion,
)
from flycrane.world.bodies import (
    Body,
    box_corners,
    obstacle_bodies,
    payload_bodies,
    platform_body,
    rotations_from_z,
)
from flycrane.world.broad_phase import (
    BoxSet,
    near_platform_boxes,
    segment_near_boxes,
    sphere_touches_boxes,
    static_boxes,
    world_boxes,
)
from flycrane.world.contact import GROUND, Clearance, Contact
from flycrane.world.scene import SceneSpec

#: fcl's nearest points of a pair are trusted for its gap's gradient when they lie this
#: close to the pair's distance apart [m]; else central differences.
NEAREST_TOLERANCE = 1e-6
#: Most robot-body-and-obstacle pairs whose bounds are computed at once (a chunk of rows).
PAIR_BOUNDS_SIZE = 1_000_000
#: Step of :meth:`CollisionChecker.gap_gradients`' central differences (m, rad), and its
#: twelve twists: each axis of translation and rotation, both ways.
TWIST_STEP = 1e-4
_TWISTS = np.vstack([np.eye(6), -np.eye(6)]) * TWIST_STEP
_TWIST_SHIFTS, _TWIST_TURNS = _TWISTS[:, :3], Rotation.from_rotvec(_TWISTS[:, 3:]).as_matrix()


@dataclass
class _Pose:
    """World poses of every robot body for N configurations."""

    position: NDArray  # (N, 3) P
    rotation: NDArray  # (N, 3, 3) R
    drones: NDArray  # (N, 3, 3)
    cable_start: NDArray  # (N, 6, 3) b_i
    cable_axis: NDArray  # (N, 6, 3) unit, b_i -> A_i
    cable_rotation: NDArray  # (N, 6, 3, 3) takes z onto the cable axis (fcl capsules)


class CollisionChecker:
    """Collision checks of configurations in one scene, for one system.

    Not picklable (fcl objects): worker processes rebuild it from (system spec, scene),
    which takes milliseconds; see :meth:`__reduce__`.
    """

    def __init__(self, system: CableSystem, scene: SceneSpec, base_dir: Path | None = None):
        self.system, self.scene, self.base_dir = system, scene, base_dir
        settings = scene.collision
        self.settings = settings
        self.obstacles = obstacle_bodies(scene, base_dir)
        self.platform_fixed: list[Body] = [
            platform_body(system, settings.platform_thickness),
            *payload_bodies(scene, base_dir),
        ]
        self._obstacle_boxes = BoxSet.of(self.obstacles)
        self._obstacle_aabb = static_boxes(self._obstacle_boxes)
        self._margins = np.array([o.margin for o in self.obstacles])
        self._fixed_boxes = BoxSet.of(self.platform_fixed)
        self._payload_boxes = BoxSet.of(self.platform_fixed[1:])
        self._request = fcl.CollisionRequest()
        self._drone = fcl.Sphere(settings.drone_radius)
        self._cables = [
            fcl.Capsule(settings.cable_radius, float(length)) for length in system.cable_lengths
        ]
        trimmed = np.maximum(system.cable_lengths - settings.cable_clearance_at_platform, 1e-3)
        self._trimmed_cables = [
            fcl.Capsule(settings.cable_radius, float(length)) for length in trimmed
        ]
        # The ground is raised by the clearance, as the obstacles are grown by it.
        self._ground_z = settings.obstacle_clearance
        self._ground = fcl.CollisionObject(fcl.Halfspace(np.array([0.0, 0.0, 1.0]), self._ground_z))

    def __reduce__(self):
        return (CollisionChecker, (self.system, self.scene, self.base_dir))

    # -- poses and boxes -------------------------------------------------------------------

    def _pose(self, q: NDArray) -> _Pose:
        # The kinematics of flycrane.model.kinematics, with R computed once for both point sets.
        p, r = q[:, :3], matrix_from_tilt_torsion(q[:, 3:6])
        b = p[:, None, :] + np.einsum("nab,ib->nia", r, self.system.platform_points)
        local = drone_positions_in_platform_frame(self.system, q[:, 6:9])
        a = p[:, None, :] + np.einsum("nab,nkb->nka", r, local)
        axis = a[:, CABLE_DRONE] - b
        axis /= np.linalg.norm(axis, axis=-1, keepdims=True)
        return _Pose(p, r, a, b, axis, rotations_from_z(axis))

    def _robot_boxes(self, pose: _Pose) -> tuple[NDArray, NDArray, list[tuple[str, int]]]:
        """World boxes of all robot bodies (N, B, 3) x2, and (kind, index) per body."""
        r_d, r_c = self.settings.drone_radius, self.settings.cable_radius
        lengths = self.system.cable_lengths[None, :, None]
        cable_end = pose.cable_start + pose.cable_axis * lengths
        fixed_c, fixed_h = world_boxes(self._fixed_boxes, pose.position, pose.rotation)
        centers = np.concatenate([pose.drones, (pose.cable_start + cable_end) / 2, fixed_c], axis=1)
        halves = np.concatenate(
            [
                np.full(pose.drones.shape, r_d),
                np.abs(cable_end - pose.cable_start) / 2 + r_c,
                fixed_h,
            ],
            axis=1,
        )
        kinds = [("drone", k) for k in range(3)] + [("cable", i) for i in range(6)]
        kinds += [("fixed", j) for j in range(len(self.platform_fixed))]
        return centers, halves, kinds

    # -- fcl objects for one configuration --------------------------------------------------

    def _robot_object(
        self, kind: str, index: int, pose: _Pose, row: int, trimmed: bool = False
    ) -> fcl.CollisionObject:
        if kind == "drone":
            return fcl.CollisionObject(self._drone, fcl.Transform(pose.drones[row, index]))
        if kind == "cable":
            axis = pose.cable_axis[row, index]
            skip = self.settings.cable_clearance_at_platform if trimmed else 0.0
            length = float(self.system.cable_lengths[index])
            middle = pose.cable_start[row, index] + axis * (skip + (length - skip) / 2)
            geometry = (self._trimmed_cables if trimmed else self._cables)[index]
            rotation = pose.cable_rotation[row, index]
            return fcl.CollisionObject(geometry, fcl.Transform(rotation, middle))
        body = self.platform_fixed[index]
        r = pose.rotation[row]
        return fcl.CollisionObject(
            body.geometry, fcl.Transform(r @ body.rotation, pose.position[row] + r @ body.center)
        )

    def _robot_geometry(self, kind: str, index: int) -> fcl.CollisionGeometry:
        """The fcl shape of a robot body."""
        if kind == "drone":
            return self._drone
        if kind == "cable":
            return self._cables[index]
        return self.platform_fixed[index].geometry

    def _name(self, kind: str, index: int) -> str:
        if kind == "fixed":
            return self.platform_fixed[index].name
        return f"{kind} {index + 1}"

    def _depth(self, a: fcl.CollisionObject, b: fcl.CollisionObject, contacts: bool) -> float:
        """0 if apart, else the penetration depth (or a tiny positive number without contacts)."""
        request = (
            fcl.CollisionRequest(num_max_contacts=1, enable_contact=True)
            if contacts
            else self._request
        )
        result = fcl.CollisionResult()
        if not fcl.collide(a, b, request, result):
            return 0.0
        if contacts and result.contacts:
            return max(float(result.contacts[0].penetration_depth), 1e-12)
        return 1e-12

    # -- checks ------------------------------------------------------------------------------

    def _self_shortfalls(self, pose: _Pose) -> tuple[NDArray, NDArray]:
        """Closed-form self-checks: by how much drone pairs (N, 3, 3) and drones against
        other drones' cables (N, 3, 6) miss their separation; > 0 means a contact."""
        s = self.settings
        gaps = np.linalg.norm(pose.drones[:, :, None] - pose.drones[:, None, :], axis=-1)
        pairs = np.where(np.triu(np.ones((3, 3), bool), 1), s.min_drone_separation - gaps, -np.inf)
        rel = pose.drones[:, :, None, :] - pose.cable_start[:, None, :, :]  # (N, 3, 6, 3)
        along = np.clip(
            np.einsum("nkia,nia->nki", rel, pose.cable_axis), 0.0, self.system.cable_lengths
        )
        closest = rel - along[..., None] * pose.cable_axis[:, None, :, :]
        cable = s.drone_radius + s.cable_radius - np.linalg.norm(closest, axis=-1)
        own = np.array(CABLE_DRONE)[None, :] == np.arange(3)[:, None]  # a drone holds its cables
        return pairs, np.where(own, -np.inf, cable)

    def _self_contacts(self, pose: _Pose, row: int) -> list[Contact]:
        pairs, cable = self._self_shortfalls(pose)
        found = [
            Contact(f"drone {k + 1}", f"drone {m + 1}", float(pairs[row, k, m]))
            for k, m in zip(*np.nonzero(pairs[row] > 0), strict=True)
        ]
        found += [
            Contact(f"drone {k + 1}", f"cable {i + 1}", float(cable[row, k, i]))
            for k, i in zip(*np.nonzero(cable[row] > 0), strict=True)
        ]
        return found

    def _self_free(self, pose: _Pose) -> NDArray[np.bool_]:
        pairs, cable = self._self_shortfalls(pose)
        return ~(np.any(pairs > 0, axis=(1, 2)) | np.any(cable > 0, axis=(1, 2)))

    def _candidate_pairs(self, pose: _Pose):
        """(row, kind, index, target) triples that need fcl; target: obstacle index,
        ``GROUND``, or ("payload", j) for robot-payload self-checks.

        Drones against obstacles: exact sphere-box test (a conservative one for non-box
        obstacles, via their bounding box); cables: slab test of the axis against boxes
        grown by the radius; platform and payload: world-box overlap; drones and cables
        against the payload's own shapes: the same tests in the platform frame.
        """
        centers, halves, kinds = self._robot_boxes(pose)
        pairs: list[tuple[int, str, int, object]] = []
        obstacles = self._obstacle_boxes
        if len(obstacles.centers):
            drone_hits = sphere_touches_boxes(pose.drones, self.settings.drone_radius, obstacles)
            for row, k, o in zip(*np.nonzero(drone_hits), strict=True):
                pairs.append((int(row), "drone", int(k), int(o)))
            ends = pose.cable_start + pose.cable_axis * self.system.cable_lengths[:, None]
            cable_hits = segment_near_boxes(
                pose.cable_start, ends, self.settings.cable_radius, obstacles
            )
            for row, i, o in zip(*np.nonzero(cable_hits), strict=True):
                pairs.append((int(row), "cable", int(i), int(o)))
            obstacle_c, obstacle_h = self._obstacle_aabb
            fixed = slice(9, None)
            overlap = np.all(
                np.abs(centers[:, fixed, None, :] - obstacle_c)
                <= halves[:, fixed, None, :] + obstacle_h,
                axis=-1,
            )
            for row, j, o in zip(*np.nonzero(overlap), strict=True):
                pairs.append((int(row), "fixed", int(j), int(o)))
        if self.scene.ground:
            low = centers[..., 2] - halves[..., 2] <= self._ground_z
            for row, body in zip(*np.nonzero(low), strict=True):
                pairs.append((int(row), *kinds[body], GROUND))
        if self.platform_fixed[1:]:  # drones and cables near the payload's shapes
            s = self.settings
            lengths = self.system.cable_lengths[:, None]
            start = pose.cable_start + pose.cable_axis * s.cable_clearance_at_platform
            end = pose.cable_start + pose.cable_axis * lengths
            drones, cables = near_platform_boxes(
                self._payload_boxes,
                pose.position,
                pose.rotation,
                (pose.drones, s.drone_radius),
                (start, end, s.cable_radius),
            )
            for row, k, j in zip(*np.nonzero(drones), strict=True):
                pairs.append((int(row), "drone", int(k), ("payload", int(j) + 1)))
            for row, i, j in zip(*np.nonzero(cables), strict=True):
                pairs.append((int(row), "cable", int(i), ("payload", int(j) + 1)))
        return pairs

    def _narrow(self, pose: _Pose, pair, contacts: bool) -> Contact | None:
        row, kind, index, target = pair
        payload_check = isinstance(target, tuple)
        mine = self._robot_object(kind, index, pose, row, trimmed=payload_check and kind == "cable")
        if target == GROUND:
            other, name = self._ground, GROUND
        elif payload_check:
            other = self._robot_object("fixed", target[1], pose, row)
            name = self.platform_fixed[target[1]].name
        else:
            body = self.obstacles[target]
            other, name = body.obstacle, body.name
            if body.margin > 0.0:  # a mesh: its faces kept at the clearance
                gap = fcl.distance(mine, other, fcl.DistanceRequest(), fcl.DistanceResult())
                if gap > body.margin:
                    return None
                return Contact(self._name(kind, index), name, body.margin - max(gap, 0.0))
        depth = self._depth(mine, other, contacts)
        return Contact(self._name(kind, index), name, depth) if depth > 0 else None

    def collision_free(self, q: ArrayLike) -> NDArray[np.bool_]:
        """True for each configuration (N, 9) whose bodies touch nothing, shape (N,)."""
        q = as_configurations(q)
        pose = self._pose(q)
        free = self._self_free(pose)
        for pair in self._candidate_pairs(pose):
            if free[pair[0]] and self._narrow(pose, pair, contacts=False) is not None:
                free[pair[0]] = False
        return free

    def first_collision(self, q: ArrayLike) -> int | None:
        """Index of the first configuration in collision, checking in order; None if none."""
        q = as_configurations(q)
        pose = self._pose(q)
        self_hits = np.flatnonzero(~self._self_free(pose))
        limit = int(self_hits[0]) if len(self_hits) else len(q)
        for pair in sorted(self._candidate_pairs(pose), key=lambda p: p[0]):
            if pair[0] >= limit:
                break
            if self._narrow(pose, pair, contacts=False) is not None:
                return pair[0]
        return limit if len(self_hits) else None

    def contacts(self, q: ArrayLike) -> list[Contact]:
        """Every contact of one configuration (9,), with penetration depths."""
        pose = self._pose(as_configurations(q)[:1])
        found = self._self_contacts(pose, 0)
        for pair in self._candidate_pairs(pose):
            contact = self._narrow(pose, pair, contacts=True)
            if contact is not None:
                found.append(contact)
        return found

    def clearance(self, q: ArrayLike) -> float:
        """Smallest distance from any robot body to any obstacle or the ground [m] (9,),
        beyond the scene's ``obstacle_clearance``: :attr:`Clearance.distance` of
        :meth:`closest`."""
        return self.closest(q).distance

    def closest(self, q: ArrayLike) -> Clearance:
        """The closest robot body and obstacle (or the ground) of one configuration (9,),
        and their distance beyond the scene's ``obstacle_clearance`` (to the grown obstacles,
        the raised ground) [m]; negative where they overlap (fcl's signed distance).

        Obstacles by fcl's distance; the ground from the lowest point of each body's world
        box, which is exact for spheres, capsules and boxes (fcl's halfspace distance
        crashes in python-fcl 0.7).
        """
        pose = self._pose(as_configurations(q)[:1])
        boxes = self._robot_boxes(pose)
        return self._closest(pose, boxes, 0, next(self._bounds_by_row(boxes)))[0]

    def gap_gradients(self, q: ArrayLike) -> tuple[NDArray, NDArray]:
        """The clearances of configurations (N, 9) (:meth:`clearance`), and each one's
        gradient in a twist of the platform (translation, rotation vector; world axes; the
        alphas kept, so every robot body moves with the platform). Between primitive
        shapes, from fcl's nearest points a (robot) and b: the unit n = (a - b) / |a - b|
        and its moment (a - c) x n about the platform's centre c. With a mesh, whose
        nearest points python-fcl 0.7 does not give in the world frame: central differences
        of fcl's distance of the closest pair, the robot body moved by the twist. At the
        ground, its lowest point's height. (N,), (N, 6); zeros where bodies touch."""
        q = as_configurations(q)
        pose = self._pose(q)
        boxes = self._robot_boxes(pose)
        request = fcl.DistanceRequest(enable_signed_distance=True)
        gaps, gradients = np.empty(len(q)), np.zeros((len(q), 6))
        for n, bounds in enumerate(self._bounds_by_row(boxes)):
            best, (kind, index, o), result = self._closest(pose, boxes, n, bounds)
            gaps[n] = best.distance
            if not best.distance > 0.0 or not np.isfinite(best.distance):
                continue
            if o < 0:  # the ground: the lowest point rises by e_z . (dp + dw x r)
                r = self._lowest_point(kind, index, pose, n) - pose.position[n]
                gradients[n] = (0.0, 0.0, 1.0, r[1], -r[0], 0.0)  # r x e_z
                continue
            center = pose.position[n]
            shapes = (self._robot_geometry(kind, index), self.obstacles[o].geometry)
            if result is not None and not any(isinstance(x, fcl.BVHModel) for x in shapes):
                a, b = (np.asarray(p, dtype=float) for p in result.nearest_points)
                apart = math.dist(a, b)
                if apart > 0.0 and abs(apart - result.min_distance) <= NEAREST_TOLERANCE:
                    (x, y, z), (u, v, w) = a - center, (a - b) / apart
                    gradients[n] = (u, v, w, y * w - z * v, z * u - x * w, x * v - y * u)
                    continue
            mine, obstacle = self._robot_object(kind, index, pose, n), self.obstacles[o].obstacle
            rotation, origin = mine.getRotation(), mine.getTranslation()
            moved = []
            for shift, turn in zip(_TWIST_SHIFTS, _TWIST_TURNS, strict=True):
                place = center + turn @ (origin - center) + shift
                mine.setTransform(fcl.Transform(turn @ rotation, place))
                moved.append(fcl.distance(mine, obstacle, request, fcl.DistanceResult()))
            gradients[n] = (np.array(moved[:6]) - moved[6:]) / (2 * TWIST_STEP)
        return gaps, gradients

    def _lowest_point(self, kind: str, index: int, pose: _Pose, row: int) -> NDArray:
        """The lowest point of a robot body (a drone's centre, a cable's lower end, a
        platform-fixed box's lowest corner) at a pose's row."""
        if kind == "drone":
            return np.asarray(pose.drones[row, index])
        if kind == "cable":
            start = pose.cable_start[row, index]
            end = start + pose.cable_axis[row, index] * self.system.cable_lengths[index]
            return np.asarray(start if start[2] < end[2] else end)
        corners = (
            pose.position[row] + box_corners(self.platform_fixed[index]) @ pose.rotation[row].T
        )
        return np.asarray(corners[np.argmin(corners[:, 2])])

    def _bounds_by_row(
        self, boxes: tuple[NDArray, NDArray, list[tuple[str, int]]]
    ) -> Iterator[tuple[NDArray, NDArray] | None]:
        """:meth:`_pair_bounds` of each row of ``boxes`` in turn (None without obstacles),
        computed for a few rows at a time: their arrays hold rows x bodies x obstacles
        numbers, which for a long path among thousands of obstacles would take gigabytes
        at once; a chunk keeps to :data:`PAIR_BOUNDS_SIZE` of them."""
        rows, bodies = boxes[0].shape[:2]
        if not self.obstacles:
            yield from itertools.repeat(None, rows)
            return
        chunk = max(1, PAIR_BOUNDS_SIZE // (bodies * len(self.obstacles)))
        for start in range(0, rows, chunk):
            yield from zip(*self._pair_bounds(boxes, slice(start, start + chunk)), strict=True)

    def _pair_bounds(
        self, boxes: tuple[NDArray, NDArray, list[tuple[str, int]]], rows: slice
    ) -> tuple[NDArray, NDArray]:
        """Lower bounds of each robot body's distance to each obstacle, from their world
        boxes (-inf where the boxes overlap: the bodies may be in contact), (R, B, O) for
        the ``rows`` of ``boxes``, and each row's pairs in their order (R, B * O): none
        farther than the closest found can be closer."""
        centers, halves = boxes[0][rows], boxes[1][rows]
        obstacle_c, obstacle_h = self._obstacle_aabb
        apart = np.abs(centers[:, :, None] - obstacle_c) - halves[:, :, None] - obstacle_h
        lower = np.linalg.norm(np.maximum(apart, 0.0), axis=-1) - self._margins
        lower[(apart <= 0.0).all(axis=-1)] = -np.inf
        flat = lower.reshape(len(lower), lower.shape[1] * lower.shape[2])
        return lower, np.argsort(flat, axis=1, kind="stable")

    def _closest(
        self,
        pose: _Pose,
        boxes: tuple[NDArray, NDArray, list[tuple[str, int]]],
        row: int,
        bounds: tuple[NDArray, NDArray] | None,
    ) -> tuple[Clearance, tuple[str, int, int], fcl.DistanceResult | None]:
        """:meth:`closest` of a pose's row (``boxes``: its :meth:`_robot_boxes`; ``bounds``:
        the row's :meth:`_pair_bounds`, None without obstacles), its pair (the robot body's
        (kind, index) and the obstacle's index, -1 for the ground) and fcl's result of an
        obstacle's pair (its nearest points)."""
        request = fcl.DistanceRequest(enable_signed_distance=True)
        all_centers, all_halves, kinds = boxes
        centers, halves = all_centers[row], all_halves[row]
        lowest = centers[:, 2] - halves[:, 2]
        best = Clearance(np.inf, "", "")
        pair = ("", -1, -1)
        if self.scene.ground:
            body = int(np.argmin(lowest))
            best = Clearance(float(lowest[body] - self._ground_z), self._name(*kinds[body]), GROUND)
            pair = (*kinds[body], -1)
        found = None
        if bounds is None:
            return best, pair, found
        lower, order = bounds
        first = len(kinds) * len(self.obstacles)  # of equally close pairs, the first listed
        for flat in order:
            b, o = divmod(int(flat), len(self.obstacles))
            if lower[b, o] > best.distance:
                break
            (kind, index), obstacle = kinds[b], self.obstacles[o]
            mine = self._robot_object(kind, index, pose, row)
            result = fcl.DistanceResult()
            gap = fcl.distance(mine, obstacle.obstacle, request, result)
            gap -= obstacle.margin  # a mesh keeps the clearance from its faces
            if gap < best.distance or (gap == best.distance and flat < first and pair[2] >= 0):
                best = Clearance(float(gap), self._name(kind, index), obstacle.name)
                pair, first, found = (kind, index, o), flat, result
        return best, pair, found
