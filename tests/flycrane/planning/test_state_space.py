"""State space, interpolation, metrics and smoothing against hand-computed values."""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from flycrane.planning.interpolation import interpolate, wrap_angle
from flycrane.planning.metrics import mechanical_work, path_metrics
from flycrane.planning.objective import MechanicalWork, PathLength
from flycrane.planning.smoothing import ShortcutConfig, shortcut_path
from flycrane.planning.state_space import ConfigurationSpace
from tests.flycrane.planning.toy_validity import ToyValidity

SPACE = ConfigurationSpace((-5, -5, 0), (5, 5, 10), 0.5, 0.3, 1.8, 2.0, 1.5)


def test_interpolation_takes_angles_the_short_way():
    a = np.array([0, 0, 0, 0.0, 0.2, -3.0, 3.1, 0.0, 0.0])
    b = np.array([2, 0, 0, 0.0, 0.2, 3.0, -3.1, 0.0, 1.0])
    mid = interpolate(a, b, [0.5])[0]
    assert mid[0] == pytest.approx(1.0)
    assert mid[4] == pytest.approx(0.2)  # a torsion about the tilted axis keeps the tilt
    assert abs(mid[5]) == pytest.approx(np.pi)  # -3.0 -> 3.0 passes through pi
    assert abs(mid[6]) == pytest.approx(np.pi)  # so does alpha1, 3.1 -> -3.1
    assert mid[8] == pytest.approx(0.5)
    np.testing.assert_allclose(interpolate(a, b, [0.0, 1.0]), np.stack([a, b]), atol=1e-15)


@given(st.floats(-100, 100))
def test_wrap_angle_range(x):
    w = wrap_angle(x)
    assert -np.pi < w <= np.pi
    assert np.cos(w) == pytest.approx(np.cos(x), abs=1e-9)


def test_distance_by_hand():
    a = np.array([0, 0, 5, 0, 0, 0, 1, 1, 1.0])
    b = a.copy()
    b[:3] += [3, 4, 0]
    assert SPACE.distance(a, b)[0] == pytest.approx(5.0)
    c = a.copy()
    c[5] = 0.01  # small yaw: rho_R * angle to second order
    assert SPACE.distance(a, c)[0] == pytest.approx(2.0 * 0.01, rel=1e-4)
    d = a.copy()
    d[6] += 0.01
    assert SPACE.distance(a, d)[0] == pytest.approx(1.5 * 0.01, rel=1e-4)


def test_distance_ignores_the_azimuth_at_zero_tilt():
    a = np.array([0, 0, 5, 0.0, 0, 0.3, 1, 1, 1])
    b = np.array([0, 0, 5, 2.5, 0, 0.3, 1, 1, 1])  # same rotation, another phi
    assert SPACE.distance(a, b)[0] == pytest.approx(0.0, abs=1e-12)


def test_uniform_samples_stay_in_bounds_and_cover_them():
    q = SPACE.sample_uniform(np.random.default_rng(0), 20000)
    assert SPACE.contains(q).all()
    assert q[:, 4].max() > 0.49 and q[:, 0].min() < -4.9
    # tilt axis uniform on the cap: cos(theta) is uniform in [cos 0.5, 1]
    assert np.mean(np.cos(q[:, 4])) == pytest.approx((1 + np.cos(0.5)) / 2, abs=2e-3)


def test_metrics_by_hand():
    path = np.array([[0, 0, 5, 0, 0, 0, 1, 1, 1.0], [1, 0, 5, 0, 0, 0, 1, 1, 1.0]])
    samples = SPACE.discretize_path(path, 0.1)
    assert len(samples) == 11
    # cost rising linearly with x then: avg = 1.5, max = 2, MW = 1, IC = 1.5 * length 1
    metrics = path_metrics(path, SPACE, lambda q: 1.0 + q[:, 0], resolution=0.1)
    assert (metrics.avg_cost, metrics.max_cost) == (pytest.approx(1.5), pytest.approx(2.0))
    assert metrics.mechanical_work == pytest.approx(1.0)
    assert metrics.cost_integral == pytest.approx(1.5)
    assert mechanical_work(np.array([1.0, 3.0, 2.0, 5.0])) == pytest.approx(5.0)
    assert mechanical_work(np.array([1.0, np.inf, np.inf, 2.0])) == np.inf  # not NaN


def test_shortcut_never_lengthens_and_stays_valid(system):
    space = ConfigurationSpace.for_system(system, (-6, -6, 1), (6, 6, 10), 0.5, 0.3, 1.8)
    validity = ToyValidity(system, space)
    zigzag = np.array(
        [[x, 2.0 * (i % 2), 4.0, 0, 0, 0, 1, 1, 1] for i, x in enumerate(np.linspace(-4, 4, 9))]
    )
    for cost_aware in (False, True):
        objective = MechanicalWork(validity.cost, space) if cost_aware else PathLength(space)
        smooth = shortcut_path(zigzag, space, validity, objective, ShortcutConfig(50), seed=3)
        before = path_metrics(zigzag, space, validity.cost)
        after = path_metrics(smooth, space, validity.cost)
        assert after.length < before.length
        np.testing.assert_array_equal(smooth[[0, -1]], zigzag[[0, -1]])
        assert all(validity.motion_is_valid(a, b) for a, b in itertools.pairwise(smooth))
        if cost_aware:
            assert after.mechanical_work <= before.mechanical_work + 1e-6 * before.max_cost


def test_shortcut_checks_the_segments_its_cut_leaves(system):
    """A wall 1 cm thin across the workspace, between two samples of a motion: the motion
    passes the checker, but a segment cut from it is sampled elsewhere and may not (7 of
    these 50 seeds' paths had one when only the shortcut itself was checked). Every motion
    of the smoothed path passes the checker (a Rescue path's cut segment once grazed a
    roof)."""
    space = ConfigurationSpace.for_system(system, (-6, -6, 1), (6, 6, 10), 0.5, 0.3, 1.8)
    wall = ((0.01, -6, 1), (0.02, 6, 10))  # between P's samples at x = 0 and 0.05
    validity = ToyValidity(system, space, boxes=[wall])
    path = np.array([[-4.0, 0, 4, 0, 0, 0, 1, 1, 1], [4.0, 0, 4, 0, 0, 0, 1, 1, 1],
                     [4.0, 4, 4, 0, 0, 0, 1, 1, 1]])  # fmt: skip
    assert all(validity.motion_is_valid(a, b) for a, b in itertools.pairwise(path))
    for seed in range(50):
        smooth = shortcut_path(
            path, space, validity, PathLength(space), ShortcutConfig(20), seed=seed
        )
        assert all(validity.motion_is_valid(a, b) for a, b in itertools.pairwise(smooth)), seed
