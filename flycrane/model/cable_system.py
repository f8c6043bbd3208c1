"""The numeric FlyCrane model derived once from a :class:`~flycrane.model.system_spec.SystemSpec`.

Everything that does not depend on the configuration is computed here, in the platform frame,
so that the per-configuration formulas (kinematics, statics) only rotate and translate it.

Drone triangles (design.md section 4): drone k hangs over the segment B_i B_j of its cables
(i, j). The apex A_k of the triangle (B_i, B_j, A_k) with sides l_i, l_j lies on a circle
centred at the foot F_k on the line B_i B_j, of radius h_k, in the plane normal to the edge:
``a'_k(alpha) = F_k + h_k (cos(alpha) n_k + sin(alpha) z_k)``. n_k is the unit normal of the
edge pointing away from the platform centroid, perpendicular to the platform normal z'; z_k
completes the right-handed frame (edge, n_k, z_k) and equals z' for a planar platform.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from flycrane.errors import FieldProblem, SystemSpecError
from flycrane.model.system_spec import DRONE_CABLES, SystemSpec

#: Drone (0-based) pulled by each cable (0-based): the inverse of DRONE_CABLES.
CABLE_DRONE: tuple[int, ...] = tuple(
    next(k for k, pair in enumerate(DRONE_CABLES) if i in pair) for i in range(6)
)


def _readonly(array: np.ndarray) -> np.ndarray:
    array = np.ascontiguousarray(array, dtype=float)
    array.setflags(write=False)
    return array


@dataclass(frozen=True, eq=False)
class CableSystem:
    """Constant arrays of one FlyCrane system (SI units; platform-frame vectors)."""

    spec: SystemSpec
    platform_points: np.ndarray  #: (6, 3) B'_i
    cable_lengths: np.ndarray  #: (6,) l_i
    drone_foot: np.ndarray  #: (3, 3) F_k
    drone_radius: np.ndarray  #: (3,) h_k, distance from F_k to the drone
    drone_outward: np.ndarray  #: (3, 3) n_k, outward edge normal in the platform plane
    drone_up: np.ndarray  #: (3, 3) z_k, completes (edge, n_k, z_k)
    platform_mass: float  #: m [kg], platform plus payload
    com_offset: np.ndarray  #: (3,) c' [m]
    drone_masses: np.ndarray  #: (3,) M_k [kg]
    max_thrusts: np.ndarray  #: (3,) h_k [N]
    tension_min: np.ndarray  #: (6,) f_lo_i [N]
    tension_max: np.ndarray  #: (6,) f_hi_i [N]
    perturbation_sqrt: np.ndarray  #: (6, 6) L with L L^T = E^-1
    gravity: float  #: g [m/s^2]

    @classmethod
    def from_spec(cls, spec: SystemSpec | None = None) -> CableSystem:
        """Build the numeric model; ``None`` gives the default benchmark system."""
        spec = spec if spec is not None else SystemSpec()
        points = spec.geometry.platform_points()
        lengths = spec.geometry.cable_lengths()
        centroid = points.mean(axis=0)
        z_axis = np.array([0.0, 0.0, 1.0])
        foot, radius, outward, up = [], [], [], []
        for k, (i, j) in enumerate(DRONE_CABLES):
            edge = points[j] - points[i]
            d = np.linalg.norm(edge)
            e = edge / d
            # Foot of the apex on the edge, from the triangle's three sides (law of cosines).
            along = (lengths[i] ** 2 - lengths[j] ** 2 + d**2) / (2.0 * d)
            foot_k = points[i] + along * e
            normal = np.cross(z_axis, e)
            if np.linalg.norm(normal) < 1e-9:
                raise SystemSpecError(
                    [FieldProblem("geometry", f"drone {k + 1}'s edge is parallel to the normal")]
                )
            normal /= np.linalg.norm(normal)
            away = foot_k - centroid
            if abs(away @ normal) < 1e-9:
                raise SystemSpecError(
                    [FieldProblem("geometry", f"drone {k + 1}'s edge passes through the centroid")]
                )
            normal *= np.sign(away @ normal)
            up_k = np.cross(e, normal)
            up_k *= np.sign(up_k[2])
            foot.append(foot_k)
            radius.append(np.sqrt(lengths[i] ** 2 - along**2))
            outward.append(normal)
            up.append(up_k)
        return cls(
            spec=spec,
            platform_points=_readonly(points),
            cable_lengths=_readonly(lengths),
            drone_foot=_readonly(np.array(foot)),
            drone_radius=_readonly(np.array(radius)),
            drone_outward=_readonly(np.array(outward)),
            drone_up=_readonly(np.array(up)),
            platform_mass=float(spec.platform_mass),
            com_offset=_readonly(np.array(spec.com_offset)),
            drone_masses=_readonly(np.array(spec.drone_mass, dtype=float)),
            max_thrusts=_readonly(np.array(spec.max_thrust, dtype=float)),
            tension_min=_readonly(np.array(spec.tension_min, dtype=float)),
            tension_max=_readonly(np.array(spec.tension_max, dtype=float)),
            perturbation_sqrt=_readonly(
                np.linalg.cholesky(np.linalg.inv(spec.perturbation.ellipsoid_matrix()))
            ),
            gravity=float(spec.gravity),
        )

    def __getstate__(self) -> dict:
        # Rebuilt from the spec in worker processes: small to send, and read-only flags survive.
        return {"spec": self.spec}

    def __setstate__(self, state: dict) -> None:
        rebuilt = CableSystem.from_spec(state["spec"])
        for name, value in rebuilt.__dict__.items():
            object.__setattr__(self, name, value)
