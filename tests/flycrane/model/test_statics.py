"""Statics against independent evidence: force balance, optimization, brute force, symmetry."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import minimize

from flycrane.model.cable_system import CABLE_DRONE, CableSystem
from flycrane.model.feasibility import Constraint, violations
from flycrane.model.kinematics import (
    drone_positions_from_configuration,
    forward_kinematics,
    platform_points_from_configuration,
)
from flycrane.model.statics import evaluate_statics, nominal_wrench, screw_jacobian
from flycrane.model.statics_kernel import compiled_statics
from flycrane.model.system_spec import DRONE_CABLES, SystemSpec
from tests.conftest import random_configurations, random_feasible_configurations

G = 9.81


def equilibrium_matrix(system: CableSystem, q: np.ndarray) -> np.ndarray:
    """Force and moment (about P) of unit cable tensions, built from the points alone."""
    b = platform_points_from_configuration(system, q)[0]
    a = drone_positions_from_configuration(system, q)[0]
    columns = []
    for i in range(6):
        direction = (a[CABLE_DRONE[i]] - b[i]) / np.linalg.norm(a[CABLE_DRONE[i]] - b[i])
        columns.append(np.concatenate([direction, np.cross(b[i] - q[:3], direction)]))
    return np.array(columns).T


def gravity_wrench(system: CableSystem, q: np.ndarray) -> np.ndarray:
    """Weight of platform plus payload as a wrench about P (force; moment of c x W)."""
    from scipy.spatial.transform import Rotation

    phi, theta, sigma = q[3:6]
    c = Rotation.from_euler("ZYZ", [phi, theta, sigma - phi]).apply(
        np.array(system.com_offset)
    )  # scipy rejects read-only
    weight = np.array([0.0, 0.0, -system.platform_mass * G])
    return np.concatenate([weight, np.cross(c, weight)])


@pytest.fixture(scope="module")
def offset_system() -> CableSystem:
    return CableSystem.from_spec(SystemSpec(com_offset=(0.1, -0.05, -0.3), platform_mass=2.0))


@pytest.mark.parametrize("name", ["system", "offset_system"])
def test_nominal_tensions_balance_the_weight(name, request):
    system = request.getfixturevalue(name)
    q = random_feasible_configurations(system, np.random.default_rng(10), 200)
    report = evaluate_statics(system, q)
    for row in range(len(q)):
        residual = equilibrium_matrix(system, q[row]) @ report.nominal_tension[
            row
        ] + gravity_wrench(system, q[row])
        np.testing.assert_allclose(residual, 0.0, atol=1e-9)
    # And in the code's own terms: J f0 = w0.
    poses = forward_kinematics(system, q)
    jf0 = np.einsum("nab,nb->na", screw_jacobian(poses), report.nominal_tension)
    np.testing.assert_allclose(jf0, nominal_wrench(system, poses.rotation), atol=1e-9)


@pytest.mark.parametrize("alpha", [0.8, 1.0, 1.2])
def test_symmetric_configuration(system, alpha):
    report = evaluate_statics(system, [0, 0, 5, 0, 0, 0, alpha, alpha, alpha])
    f0, v, m = report.nominal_tension[0], report.half_width[0], report.thrust_bound[0]
    np.testing.assert_allclose(f0, f0[0], rtol=1e-12)
    np.testing.assert_allclose(v, v[0], rtol=1e-12)
    np.testing.assert_allclose(m, m[0], rtol=1e-12)
    # Vertical balance by hand: 6 f0 sin(elevation) = m g, elevation from the triangle.
    height = np.sqrt(2.0**2 - 0.7**2) * np.sin(alpha)
    assert f0[0] == pytest.approx(1.5 * G / (6 * height / 2.0), rel=1e-12)
    if alpha == 1.0:  # design.md section 5
        assert f0[0] == pytest.approx(3.11, abs=0.01)
        assert v[0] == pytest.approx(1.18, abs=0.01)
        assert m[0] == pytest.approx(17.14, abs=0.01)
        assert report.feasible[0]


def test_alpha_14_lets_a_cable_go_slack(system):
    report = evaluate_statics(system, [0, 0, 5, 0, 0, 0, 1.4, 1.4, 1.4])
    assert not report.feasible[0]
    found = violations(report)
    assert {v.constraint for v in found} == {Constraint.SLACK}
    assert all(v.limit == pytest.approx(0.5) and v.value < 0.5 for v in found)


def test_tension_ranges_contain_every_wrench_of_the_ellipsoid(offset_system):
    system = offset_system
    rng = np.random.default_rng(11)
    e_inv_sqrt = np.linalg.cholesky(np.linalg.inv(system.spec.perturbation.ellipsoid_matrix()))
    for q in random_feasible_configurations(system, rng, 20):
        report = evaluate_statics(system, q)
        a = equilibrium_matrix(system, q)
        w0 = -gravity_wrench(system, q)
        s = rng.normal(size=(5000, 6))
        s /= np.linalg.norm(s, axis=1, keepdims=True)
        wrenches = w0 + s @ e_inv_sqrt.T  # boundary: (w - w0)^T E (w - w0) = 1
        tensions = np.linalg.solve(a, wrenches.T).T
        assert np.all(tensions >= report.tension_low[0] - 1e-9)
        assert np.all(tensions <= report.tension_high[0] + 1e-9)


def test_tension_range_extremes_are_attained(system):
    """An optimizer over the ellipsoid reaches t_lo and t_hi of every cable."""
    e = system.spec.perturbation.ellipsoid_matrix()
    for q in random_feasible_configurations(system, np.random.default_rng(12), 3):
        report = evaluate_statics(system, q)
        a_inv = np.linalg.inv(equilibrium_matrix(system, q))
        w0 = -gravity_wrench(system, q)
        on_ellipsoid = {"type": "ineq", "fun": lambda d: 1.0 - d @ e @ d}
        for i in range(6):
            for sign, bound in ((1.0, report.tension_high[0, i]), (-1.0, report.tension_low[0, i])):
                best = minimize(
                    lambda d, i=i, sign=sign, a_inv=a_inv, w0=w0: -sign * (a_inv[i] @ (w0 + d)),
                    x0=np.full(6, 1e-3),
                    constraints=[on_ellipsoid],
                    method="SLSQP",
                    options={"ftol": 1e-14, "maxiter": 500},
                )
                attained = a_inv[i] @ (w0 + best.x)
                assert attained == pytest.approx(bound, rel=1e-3)


def test_thrust_bound_is_the_maximum_over_the_tension_box(system):
    q_all = random_feasible_configurations(system, np.random.default_rng(13), 30)
    grid = np.linspace(-1.0, 1.0, 81)
    li, lj = np.meshgrid(grid, grid)
    for q in q_all:
        report = evaluate_statics(system, q)
        b = platform_points_from_configuration(system, q)[0]
        a = drone_positions_from_configuration(system, q)[0]
        for k, (i, j) in enumerate(DRONE_CABLES):
            w_i = (b[i] - a[k]) / np.linalg.norm(b[i] - a[k])
            w_j = (b[j] - a[k]) / np.linalg.norm(b[j] - a[k])
            ti = report.nominal_tension[0, i] + li * report.half_width[0, i]
            tj = report.nominal_tension[0, j] + lj * report.half_width[0, j]
            weight = np.array([0.0, 0.0, -system.drone_masses[k] * G])
            thrust = -(weight + ti[..., None] * w_i + tj[..., None] * w_j)
            magnitude = np.linalg.norm(thrust, axis=-1)
            assert magnitude.max() <= report.thrust_bound[0, k] * (1 + 1e-12)
            assert magnitude.max() == pytest.approx(report.thrust_bound[0, k], rel=1e-12)


def test_singular_jacobian_is_reported_not_nan(system):
    # alpha = 0: every cable lies in the platform plane, nothing holds the weight.
    with np.errstate(all="raise"):
        report = evaluate_statics(system, [0, 0, 5, 0, 0, 0, 0, 0, 0])
        f0, v, m, cost = compiled_statics(system, [0, 0, 5, 0, 0, 0, 0, 0, 0])
    assert report.singular[0]
    assert not report.feasible[0]
    for array in (
        report.nominal_tension,
        report.tension_low,
        report.tension_high,
        report.thrust_bound,
        report.slack_margin,
        f0,
        v,
        m,
        cost,
    ):
        assert not np.isnan(array).any()
    assert cost[0] == np.inf
    assert [x.constraint for x in violations(report)] == [Constraint.SINGULAR]


def test_compiled_kernel_matches_the_numpy_reference(system):
    rng = np.random.default_rng(14)
    q = random_configurations(rng, 3000, max_tilt=1.5)
    q[:20, 6:] = 0.0  # singular rows
    report = evaluate_statics(system, q)
    f0, v, m, _ = compiled_statics(system, q)
    np.testing.assert_array_equal(np.isinf(f0[:, 0]), report.singular)
    ok = ~report.singular
    np.testing.assert_allclose(f0[ok], report.nominal_tension[ok], rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(v[ok], report.half_width[ok], rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(m[ok], report.thrust_bound[ok], rtol=1e-9, atol=1e-9)
