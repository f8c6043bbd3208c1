"""Kinematics against independent evidence: scipy rotations, cable lengths, analytic poses."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from flycrane.errors import ConfigurationError
from flycrane.model.cable_system import CABLE_DRONE, CableSystem
from flycrane.model.direct_kinematics import configuration_from_drone_positions
from flycrane.model.kinematics import (
    as_configurations,
    drone_positions_from_configuration,
    matrix_from_tilt_torsion,
    platform_points_from_configuration,
    tilt_torsion_from_matrix,
)
from flycrane.model.system_spec import GenericGeometry, SystemSpec
from tests.conftest import random_configurations, random_feasible_configurations

angles = st.tuples(st.floats(-np.pi, np.pi), st.floats(0.0, np.pi - 1e-6), st.floats(-np.pi, np.pi))


@given(angles)
def test_rotation_is_the_paper_composition_of_elementary_rotations(tau):
    phi, theta, sigma = tau
    # scipy's intrinsic "ZYZ" applies Rz(phi) Ry(theta) Rz(sigma - phi) in that order.
    expected = Rotation.from_euler("ZYZ", [phi, theta, sigma - phi]).as_matrix()
    r = matrix_from_tilt_torsion(np.array(tau))
    np.testing.assert_allclose(r, expected, atol=1e-12)
    np.testing.assert_allclose(r @ r.T, np.eye(3), atol=1e-12)
    assert np.linalg.det(r) == pytest.approx(1.0, abs=1e-12)


@given(angles)
def test_tilt_torsion_round_trip_gives_the_same_rotation(tau):
    r = matrix_from_tilt_torsion(np.array(tau))
    recovered = tilt_torsion_from_matrix(r)
    assert 0.0 <= recovered[1] <= np.pi
    np.testing.assert_allclose(matrix_from_tilt_torsion(recovered), r, atol=1e-9)


@pytest.mark.parametrize("tilt_scale", [1e-15, 1e-9, 1e-6])
def test_round_trip_keeps_tilts_too_small_for_arccos(tilt_scale):
    # cos(theta) rounds to 1 below theta ~ 1e-8 rad: the tilt must come from sin(theta).
    rng = np.random.default_rng(7)
    tau = np.stack(
        [
            rng.uniform(-np.pi, np.pi, 1000),
            rng.uniform(0, tilt_scale, 1000),
            rng.uniform(-np.pi, np.pi, 1000),
        ],
        axis=-1,
    )
    for tilts in (tau, tau * [1, -1, 1] + [0, np.pi, 0]):  # near theta = 0 and near pi
        r = matrix_from_tilt_torsion(tilts)
        np.testing.assert_allclose(
            matrix_from_tilt_torsion(tilt_torsion_from_matrix(r)), r, atol=1e-14
        )


def test_zero_tilt_torsion_is_yaw():
    r = matrix_from_tilt_torsion([[0.7, 0.0, 0.3]])[0]
    np.testing.assert_allclose(r, Rotation.from_euler("z", 0.3).as_matrix(), atol=1e-15)
    np.testing.assert_allclose(tilt_torsion_from_matrix(r), [0.0, 0.0, 0.3], atol=1e-15)


def test_every_cable_has_its_length(system):
    q = random_configurations(np.random.default_rng(1), 2000, max_tilt=np.pi - 0.1)
    b = platform_points_from_configuration(system, q)
    a = drone_positions_from_configuration(system, q)
    lengths = np.linalg.norm(a[:, CABLE_DRONE] - b, axis=-1)
    np.testing.assert_allclose(lengths, 2.0, atol=1e-12)


def test_generic_cables_have_their_lengths():
    rng = np.random.default_rng(2)
    spec = SystemSpec(
        geometry=GenericGeometry(
            platform_points=[
                (0.8, -0.1, 0.0),
                (0.8, 0.1, 0.05),
                (-0.3, 0.7, 0.0),
                (-0.5, 0.6, 0.0),
                (-0.5, -0.6, -0.05),
                (-0.3, -0.7, 0.0),
            ],
            cable_lengths=[1.8, 2.0, 2.1, 1.9, 2.2, 2.0],
        )
    )
    system = CableSystem.from_spec(spec)
    q = random_configurations(rng, 500)
    b = platform_points_from_configuration(system, q)
    a = drone_positions_from_configuration(system, q)
    np.testing.assert_allclose(
        np.linalg.norm(a[:, CABLE_DRONE] - b, axis=-1),
        np.broadcast_to(system.cable_lengths, (500, 6)),
        atol=1e-12,
    )


def test_octahedral_drones_by_hand(system):
    # Level platform at P = (1, 2, 5), alpha = pi/2: drone k straight above its edge's
    # midpoint, at the triangle's height sqrt(l^2 - (s/2)^2) = sqrt(4 - 0.49).
    q = [1.0, 2.0, 5.0, 0.0, 0.0, 0.0, np.pi / 2, np.pi / 2, np.pi / 2]
    r = 1.4 / np.sqrt(3)
    v = np.array([[r * np.cos(t), r * np.sin(t), 0.0] for t in np.radians([0, 120, 240])])
    midpoints = np.array([(v[2] + v[0]) / 2, (v[0] + v[1]) / 2, (v[1] + v[2]) / 2])
    expected = midpoints + [1.0, 2.0, 5.0 + np.sqrt(4.0 - 0.49)]
    np.testing.assert_allclose(drone_positions_from_configuration(system, q)[0], expected)
    # alpha < pi/2 leans the drone outward: drone 3's edge is on the -x side.
    leaning = drone_positions_from_configuration(system, [0, 0, 5, 0, 0, 0, 1, 1, 1])[0]
    assert leaning[2, 0] < midpoints[2, 0]


def test_direct_kinematics_recovers_configurations(system):
    q = random_feasible_configurations(system, np.random.default_rng(3), 300)
    result = configuration_from_drone_positions(
        system, drone_positions_from_configuration(system, q)
    )
    assert result.converged.all()
    np.testing.assert_allclose(result.q[:, :3], q[:, :3], atol=1e-8)
    np.testing.assert_allclose(result.q[:, 6:], q[:, 6:], atol=1e-8)
    np.testing.assert_allclose(
        matrix_from_tilt_torsion(result.q[:, 3:6]), matrix_from_tilt_torsion(q[:, 3:6]), atol=1e-8
    )


def test_direct_kinematics_reports_unreachable_drone_positions(system):
    drones = drone_positions_from_configuration(system, [0, 0, 5, 0, 0, 0, 1, 1, 1])
    drones[0, 0] += [10.0, 0.0, 0.0]  # drone 1 far beyond its cables' reach
    result = configuration_from_drone_positions(system, drones)
    assert not result.converged[0]
    assert np.abs(result.length_error).max() > 1.0


@pytest.mark.parametrize(
    ("q", "field"),
    [
        ([0, 0, 5, 0, 0, 0, 1, 1], "q"),
        ([0, 0, np.nan, 0, 0, 0, 1, 1, 1], "q.z"),
        ([0, 0, 5, 0, -0.1, 0, 1, 1, 1], "q.theta"),
        ([[0, 0, 5, 0, 0, 0, 1, 1, 1], [0, 0, 5, 0, 0, np.inf, 1, 1, 1]], "q[1].sigma"),
        ([[0, 0, 5, 0, -0.1, 0, 1, 1, 1]], "q[0].theta"),  # a list of one is still a list
        ("abc", "q"),
    ],
)
def test_bad_configurations_name_the_field(q, field):
    with pytest.raises(ConfigurationError) as info:
        as_configurations(q)
    assert info.value.problems[0].field == field
