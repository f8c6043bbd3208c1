"""The linearized platform error against the exact direct kinematics of perturbed drones."""

from __future__ import annotations

import numpy as np
import pytest

from flycrane.model.direct_kinematics import configuration_from_drone_positions
from flycrane.model.kinematics import (
    drone_positions_from_configuration,
    matrix_from_tilt_torsion,
)
from flycrane.model.pose_error import displacement_bound, height_bound, point_sensitivity
from tests.flycrane.model.sampling import feasible_configurations

#: The Rescue's footbridge ends and the Puzzle-like offset point, in the platform frame.
POINTS = np.array([[2.3, 0.4, -0.4], [-2.3, -0.4, -0.4], [0.0, 0.0, -0.35]])


@pytest.fixture(scope="module")
def configurations():
    """Feasible configurations of the Rescue's space."""
    return feasible_configurations("rescue", 5, 20)


def moved_points(system, q, drones):
    """The points where the exact direct kinematics puts them for drones (S, 3, 3)."""
    solved = configuration_from_drone_positions(
        system, drones, initial=np.repeat(q[None], len(drones), 0)
    )
    assert solved.converged.all()
    rotation = matrix_from_tilt_torsion(solved.q[:, 3:6])
    return solved.q[:, None, :3] + np.einsum("sab,pb->spa", rotation, POINTS)


def test_the_sensitivity_is_the_derivative_of_the_direct_kinematics(configurations):
    """Central differences of the exact solve, 1 mm per drone coordinate."""
    system, qs = configurations
    q = qs[0]
    drones = drone_positions_from_configuration(system, q)[0]
    step = 1e-3
    columns = []
    for j in range(9):
        delta = np.zeros(9)
        delta[j] = step
        up = moved_points(system, q, (drones + delta.reshape(3, 3))[None])[0]
        down = moved_points(system, q, (drones - delta.reshape(3, 3))[None])[0]
        columns.append((up - down) / (2 * step))
    numeric = np.stack(columns, axis=-1)  # (P, 3, 9)
    np.testing.assert_allclose(point_sensitivity(system, q, POINTS)[0], numeric, atol=2e-5)


def displaced(system, q, own, common_shift, rng):
    """How far the points move (300, P, 3), solved exactly, for drone errors at the corners
    of their bounds (the worst a linear map reaches): each drone's own error at its
    horizontal radius in a random direction and at a vertical bound, plus ``common_shift``
    with a random sign."""
    drones = drone_positions_from_configuration(system, q)[0]
    angle = rng.uniform(0, 2 * np.pi, (300, 3))
    errors = np.stack(
        [own[0] * np.cos(angle), own[0] * np.sin(angle),
         own[1] * rng.choice([-1.0, 1.0], (300, 3))], axis=-1,
    )  # fmt: skip
    shift = np.asarray(common_shift) * rng.choice([-1.0, 1.0], (300, 1, 1))
    moved = moved_points(system, q, drones[None] + errors + shift)
    return moved - moved_points(system, q, drones[None])[0]


def test_the_bound_covers_sampled_errors_and_is_not_loose(configurations):
    """Drone errors at the corners of their bounds, solved exactly: every displacement
    within the bound (plus the second-order term), and the worst sample at least half of
    it."""
    system, qs = configurations
    common, own = (0.04, 0.04), (0.02, 0.013)
    rng = np.random.default_rng(3)
    worst = []
    for q in qs:
        shift = [common[0], 0.0, common[1]]
        displacement = np.linalg.norm(displaced(system, q, own, shift, rng), axis=-1)
        bound = displacement_bound(system, q, POINTS, common, own)[0]
        assert np.all(displacement <= bound * 1.02 + 1e-4), (displacement.max(0), bound)
        worst.append(displacement.max(0) / bound)
    assert np.median(worst) > 0.5


def test_the_height_bound_covers_sampled_errors_and_is_not_loose(configurations):
    """The same for the vertical displacement alone, the common error at its vertical
    bound: never beyond the bound, and the worst sample at least half of it. It is never
    more than the whole displacement's bound."""
    system, qs = configurations
    common, own = (0.04, 0.04), (0.02, 0.013)
    rng = np.random.default_rng(4)
    worst = []
    for q in qs:
        sink = np.abs(displaced(system, q, own, [0.0, 0.0, common[1]], rng)[..., 2])
        bound = height_bound(system, q, POINTS, common[1], own)[0]
        assert np.all(sink <= bound * 1.02 + 1e-4), (sink.max(0), bound)
        assert np.all(bound <= displacement_bound(system, q, POINTS, common, own)[0] + 1e-12)
        worst.append(sink.max(0) / bound)
    assert np.median(worst) > 0.5
