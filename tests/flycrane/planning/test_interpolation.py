"""The local path: geodesic on SO(3) against scipy's Slerp, and the one discretization."""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from scipy.spatial.transform import Rotation, Slerp

from flycrane.model.kinematics import matrix_from_tilt_torsion
from flycrane.planning.interpolation import interpolate
from flycrane.planning.state_space import ConfigurationSpace

SPACE = ConfigurationSpace((-5, -5, 0), (5, 5, 10), 0.5, 0.3, 1.8, 2.0, 1.5)


def random_configurations(rng: np.random.Generator, n: int) -> np.ndarray:
    q = np.empty((n, 9))
    q[:, :3] = rng.normal(size=(n, 3))
    q[:, 3] = rng.uniform(-np.pi, np.pi, n)
    q[:, 4] = rng.uniform(0.0, np.pi, n)  # the whole chart, flips included
    q[:, 5] = rng.uniform(-np.pi, np.pi, n)
    q[:, 6:] = rng.uniform(0.0, np.pi, (n, 3))
    return q


def test_rotations_follow_scipy_slerp():
    """Orientations along 500 random local paths are scipy's Slerp of the end rotations
    (the SO(3) geodesic), to rounding."""
    rng = np.random.default_rng(7)
    a, b = random_configurations(rng, 500), random_configurations(rng, 500)
    t = np.linspace(0.0, 1.0, 9)
    worst = 0.0
    for qa, qb in zip(a, b, strict=True):
        ends = Rotation.from_matrix(matrix_from_tilt_torsion(np.stack([qa[3:6], qb[3:6]])))
        expected = Slerp([0.0, 1.0], ends)(t).as_matrix()
        ours = matrix_from_tilt_torsion(interpolate(qa, qb, t)[:, 3:6])
        worst = max(worst, float(np.abs(ours - expected).max()))
    assert worst < 1e-12


def test_positions_linear_and_alphas_short_way():
    rng = np.random.default_rng(8)
    a, b = random_configurations(rng, 200), random_configurations(rng, 200)
    t = rng.uniform(0, 1, 200)
    q = interpolate(a, b, t)
    np.testing.assert_allclose(q[:, :3], a[:, :3] + t[:, None] * (b[:, :3] - a[:, :3]))
    step = np.angle(np.exp(1j * (b[:, 6:] - a[:, 6:])))  # the short way, in (-pi, pi]
    np.testing.assert_allclose(np.cos(q[:, 6:]), np.cos(a[:, 6:] + t[:, None] * step), atol=1e-12)
    np.testing.assert_allclose(np.sin(q[:, 6:]), np.sin(a[:, 6:] + t[:, None] * step), atol=1e-12)


def test_reversing_tilt_axis_passes_level():
    """Tilts of 0.3 about opposite axes: the geodesic levels the platform half way (a 0.6
    rad rotation), where the chart's straight line kept the tilt and swung the axis."""
    a = np.array([0, 0, 5, 0.0, 0.3, 0.0, 1, 1, 1])
    b = np.array([0, 0, 5, np.pi, 0.3, 0.0, 1, 1, 1])
    mid = interpolate(a, b, [0.5])[0]
    assert mid[4] == pytest.approx(0.0, abs=1e-12)
    # The rotation angle from a to b is 0.6 rad: the path's length is rho_R * 0.6.
    assert SPACE.path_length(a, b)[0] == pytest.approx(2.0 * 0.6)


def test_discretize_pieces_are_at_most_the_resolution():
    rng = np.random.default_rng(9)
    a, b = random_configurations(rng, 100), random_configurations(rng, 100)
    for qa, qb in zip(a, b, strict=True):
        q = SPACE.discretize(qa, qb, 0.05)
        np.testing.assert_array_equal(q[[0, -1]], interpolate(qa, qb, [0.0, 1.0]))
        steps = SPACE.distance(q[:-1], q[1:])
        assert steps.max() <= 0.05 + 1e-12
        # as few pieces as that allows: the path's length over the resolution, rounded up
        length = SPACE.path_length(qa, qb)[0]
        assert len(q) - 1 == max(1, int(np.ceil(length / 0.05)))
        # the pieces are equal along the path: each rotation step is the same angle
        rotations = Rotation.from_matrix(matrix_from_tilt_torsion(q[:, 3:6]))
        angles = (rotations[:-1].inv() * rotations[1:]).magnitude()
        np.testing.assert_allclose(angles, angles[0], atol=1e-9)


def test_path_length_is_never_below_the_chordal_distance():
    rng = np.random.default_rng(10)
    a, b = random_configurations(rng, 2000), random_configurations(rng, 2000)
    assert np.all(SPACE.path_length(a, b) >= SPACE.distance(a, b) - 1e-12)


def test_discretize_path_keeps_every_waypoint_once():
    path = np.array(
        [
            [0, 0, 5, 0, 0, 0, 1, 1, 1.0],
            [1, 0, 5, 0, 0, 0, 1, 1, 1.0],
            [1, 1, 5, 0, 0, 1, 1, 1, 1.0],
        ]
    )
    q = SPACE.discretize_path(path, 0.1)
    for waypoint in path:
        assert np.sum(np.all(np.isclose(q, waypoint), axis=1)) == 1
    assert all(SPACE.distance(x, y)[0] <= 0.1 + 1e-12 for x, y in itertools.pairwise(q))
