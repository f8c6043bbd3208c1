"""The compiled direct kinematics against the numpy reference (flycrane.model.direct_kinematics)."""

from __future__ import annotations

import numpy as np

from flycrane.model.direct_kinematics import configuration_from_drone_positions
from flycrane.model.direct_kinematics_kernel import compiled_direct_kinematics
from flycrane.model.kinematics import drone_positions_from_configuration, matrix_from_tilt_torsion
from tests.conftest import random_feasible_configurations


def test_compiled_direct_kinematics_matches_the_reference_from_a_nearby_start(system):
    rng = np.random.default_rng(5)
    q = random_feasible_configurations(system, rng, 300)
    # Measured drones a few centimetres off the planned ones, as the timing tolerance has.
    drones = drone_positions_from_configuration(system, q) + rng.normal(0, 0.02, (300, 3, 3))
    reference = configuration_from_drone_positions(system, drones, initial=q)
    compiled = compiled_direct_kinematics(system, drones, q)
    assert compiled.converged.all() and reference.converged.all()
    assert np.abs(compiled.length_error).max() <= 1e-10
    # Both converge to the same pose; they differ in rounding and in their last step.
    np.testing.assert_allclose(compiled.q[:, :3], reference.q[:, :3], atol=1e-7)
    np.testing.assert_allclose(compiled.q[:, 6:], reference.q[:, 6:], atol=1e-7)
    np.testing.assert_allclose(
        matrix_from_tilt_torsion(compiled.q[:, 3:6]),
        matrix_from_tilt_torsion(reference.q[:, 3:6]),
        atol=1e-7,
    )


def test_compiled_direct_kinematics_reports_unreachable_drone_positions(system):
    q = np.array([[0, 0, 5, 0, 0, 0, 1, 1, 1], [0, 0, 5, 0, 0.1, 0, 1, 1.1, 0.9]], dtype=float)
    drones = drone_positions_from_configuration(system, q)
    drones[0, 0] += [10.0, 0.0, 0.0]  # drone 1 far beyond its cables' reach
    result = compiled_direct_kinematics(system, drones, q)
    assert not result.converged[0] and result.converged[1]
    assert np.abs(result.length_error[0]).max() > 1.0
    np.testing.assert_allclose(result.q[1], q[1], atol=1e-8)
