"""The configuration space C = SE(3) x T^3 in tilt-and-torsion parameters (OMPL's StateSpace role).

Distance. The planner needs a metric that does not depend on the chart: at zero tilt the
azimuth phi means nothing, so differences of raw angles would call two identical poses far
apart. We use the chordal metric of an embedding,

    E(q) = [p, rho_R / sqrt(2) vec(R(phi, theta, sigma)), rho_a cos(alpha_k), rho_a sin(alpha_k)],
    d(a, b) = |E(a) - E(b)|,

which equals sqrt(|dp|^2 + (rho_R w)^2 + sum_k (rho_a d_alpha_k)^2) to second order (w the
rotation angle between the two orientations), is a true metric, and makes nearest-neighbour
queries one vectorized Euclidean computation. rho_R and rho_a are lever arms in metres per
radian, by default the largest distance from P to a drone and the largest apex radius h_k,
so a unit of distance is about a metre of drone travel.

Sampling is uniform in the scene bounds: position in a box, tilt axis uniform on the cap
theta <= max_tilt (cos theta uniform, phi uniform), torsion sigma uniform in its range (the
full circle unless the scene narrows it), alphas uniform in their range.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from flycrane.model.cable_system import CableSystem
from flycrane.model.kinematics import drone_positions_in_platform_frame, matrix_from_tilt_torsion
from flycrane.planning.interpolation import (
    discretize_into,
    geodesic_lengths,
    interpolate,
    segment_count,
    wrap_angle,
)

#: Width of the embedding E(q).
EMBEDDING_SIZE = 3 + 9 + 6


def _floats(values: tuple[float, float, float]) -> tuple[float, float, float]:
    x, y, z = values
    return float(x), float(y), float(z)


@dataclass(frozen=True)
class ConfigurationSpace:
    """Bounds, metric and sampling of the FlyCrane's configurations."""

    position_low: tuple[float, float, float]
    position_high: tuple[float, float, float]
    max_tilt: float  #: [rad]
    alpha_low: float  #: [rad]
    alpha_high: float  #: [rad]
    rotation_weight: float = 2.0  #: rho_R [m/rad]
    alpha_weight: float = 1.9  #: rho_a [m/rad]
    sigma_low: float = -np.pi  #: torsion range [rad]; the full circle by default
    sigma_high: float = np.pi

    @classmethod
    def for_system(
        cls,
        system: CableSystem,
        position_low: tuple[float, float, float],
        position_high: tuple[float, float, float],
        max_tilt: float,
        alpha_low: float,
        alpha_high: float,
        sigma_low: float = -np.pi,
        sigma_high: float = np.pi,
    ) -> ConfigurationSpace:
        """Bounds as given; metric weights from the system's lever arms (module docstring)."""
        drones = drone_positions_in_platform_frame(system, np.ones((1, 3)))[0]
        return cls(
            position_low=_floats(position_low),
            position_high=_floats(position_high),
            max_tilt=float(max_tilt),
            alpha_low=float(alpha_low),
            alpha_high=float(alpha_high),
            rotation_weight=float(np.linalg.norm(drones, axis=1).max()),
            alpha_weight=float(system.drone_radius.max()),
            sigma_low=float(sigma_low),
            sigma_high=float(sigma_high),
        )

    def embed(self, q: ArrayLike) -> NDArray[np.float64]:
        """Embedding E(q) of configurations (N, 9) -> (N, 18); distances are Euclidean in it."""
        q = np.atleast_2d(np.asarray(q, dtype=float))
        rotation = matrix_from_tilt_torsion(q[:, 3:6]).reshape(len(q), 9)
        alpha = q[:, 6:9]
        return np.concatenate(
            [
                q[:, :3],
                rotation * (self.rotation_weight / np.sqrt(2.0)),
                self.alpha_weight * np.cos(alpha),
                self.alpha_weight * np.sin(alpha),
            ],
            axis=1,
        )

    def distance(self, a: ArrayLike, b: ArrayLike) -> NDArray[np.float64]:
        """d(a, b) for configurations broadcast against each other, shape (N,)."""
        return np.linalg.norm(self.embed(a) - self.embed(b), axis=1)

    def interpolate(self, a: ArrayLike, b: ArrayLike, t: ArrayLike) -> NDArray[np.float64]:
        """The local path (see :mod:`flycrane.planning.interpolation`)."""
        return interpolate(a, b, t)

    def path_length(self, a: ArrayLike, b: ArrayLike) -> NDArray[np.float64]:
        """Length of the local paths a -> b (row by row, broadcast), shape (N,): the
        geodesic's, never below :meth:`distance`."""
        a, b = np.broadcast_arrays(np.atleast_2d(a).astype(float), np.atleast_2d(b).astype(float))
        out = np.empty(len(a))
        geodesic_lengths(
            np.ascontiguousarray(a),
            np.ascontiguousarray(b),
            self.rotation_weight,
            self.alpha_weight,
            out,
        )
        return out

    def discretize(self, a: ArrayLike, b: ArrayLike, resolution: float) -> NDArray[np.float64]:
        """The local path a -> b as configurations at most ``resolution`` apart along it,
        both ends included, shape (K, 9) with K >= 2.

        The one discretization of a motion: validity checks, smoothing, path metrics and
        drone tracks all sample motions through it.
        """
        if not resolution > 0:
            raise ValueError(f"resolution must be > 0, got {resolution}")
        a = np.ascontiguousarray(a, dtype=float).reshape(9)
        b = np.ascontiguousarray(b, dtype=float).reshape(9)
        pieces = segment_count(a, b, resolution, self.rotation_weight, self.alpha_weight)
        out = np.empty((pieces + 1, 9))
        discretize_into(a, b, pieces, out)
        return out

    def discretize_path(self, path: ArrayLike, resolution: float) -> NDArray[np.float64]:
        """A path's motions discretized (:meth:`discretize`), waypoints kept once, (K, 9)."""
        path = np.atleast_2d(np.asarray(path, dtype=float))
        if len(path) < 2:
            return path.copy()
        pieces = [path[:1]] + [
            self.discretize(a, b, resolution)[1:] for a, b in itertools.pairwise(path)
        ]
        return np.concatenate(pieces)

    def point_at_length(
        self, path: NDArray[np.float64], cumulative: NDArray[np.float64], s: float
    ) -> tuple[int, NDArray[np.float64]]:
        """(segment index, configuration) at length ``s`` along ``path`` (M, 9), whose
        waypoints lie at the lengths ``cumulative`` (M,) from its start."""
        segment = int(np.clip(np.searchsorted(cumulative, s, side="right") - 1, 0, len(path) - 2))
        span = cumulative[segment + 1] - cumulative[segment]
        t = 0.0 if span <= 0 else (s - cumulative[segment]) / span
        return segment, self.interpolate(path[segment], path[segment + 1], [t])[0]

    def without_repeats(self, path: NDArray[np.float64]) -> NDArray[np.float64]:
        """``path`` (M, 9) without consecutive duplicate configurations."""
        if len(path) < 2:
            return path
        keep = np.concatenate([[True], self.distance(path[:-1], path[1:]) > 1e-12])
        return path[keep]

    def contains(self, q: ArrayLike) -> NDArray[np.bool_]:
        """True where q lies inside the sampling bounds, shape (N,)."""
        q = np.atleast_2d(np.asarray(q, dtype=float))
        low, high = np.array(self.position_low), np.array(self.position_high)
        alpha = q[:, 6:9]
        return (
            np.all((q[:, :3] >= low) & (q[:, :3] <= high), axis=1)
            & (q[:, 4] <= self.max_tilt)
            & np.all((alpha >= self.alpha_low) & (alpha <= self.alpha_high), axis=1)
            & self.sigma_in_range(q[:, 5])
        )

    def sigma_in_range(self, sigma: ArrayLike) -> NDArray[np.bool_]:
        """True where the torsion lies in [sigma_low, sigma_high] on the circle."""
        offset = np.remainder(np.asarray(sigma, dtype=float) - self.sigma_low, 2 * np.pi)
        span = self.sigma_high - self.sigma_low
        # 1e-12: the range's own end points must pass after wrapping round-off
        return (offset <= span + 1e-12) | (offset >= 2 * np.pi - 1e-12)

    def sample_uniform(self, rng: np.random.Generator, n: int = 1) -> NDArray[np.float64]:
        """n configurations uniform in the bounds (module docstring), shape (n, 9)."""
        q = np.empty((n, 9))
        q[:, :3] = rng.uniform(self.position_low, self.position_high, (n, 3))
        q[:, 3] = rng.uniform(-np.pi, np.pi, n)
        q[:, 4] = np.arccos(rng.uniform(np.cos(self.max_tilt), 1.0, n))
        q[:, 5] = wrap_angle(rng.uniform(self.sigma_low, self.sigma_high, n))
        q[:, 6:9] = rng.uniform(self.alpha_low, self.alpha_high, (n, 3))
        return q

    @property
    def maximum_extent(self) -> float:
        """Largest distance between two configurations in the bounds (an upper bound)."""
        box = np.linalg.norm(np.subtract(self.position_high, self.position_low))
        # Rotation chord is at most 2 sqrt(2) rho_R / sqrt(2); each alpha chord at most 2.
        rotation = 2.0 * self.rotation_weight
        alpha = (
            self.alpha_weight
            * np.sqrt(3.0)
            * 2.0
            * np.sin(min(np.pi, self.alpha_high - self.alpha_low) / 2.0)
        )
        return float(np.sqrt(box**2 + rotation**2 + alpha**2))
