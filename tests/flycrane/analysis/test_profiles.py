"""Profiles along paths: positions along the path by length, statics at each step, plots."""

from __future__ import annotations

import numpy as np
import pytest

from flycrane.analysis.profiles import (
    configurations_at_fractions,
    least_margins,
    path_profile,
    plot_path_profile,
    plot_profile_bands,
)
from flycrane.model.statics import evaluate_statics
from flycrane.planning.state_space import ConfigurationSpace

SPACE = ConfigurationSpace((-5, -5, 0), (5, 5, 10), 0.5, 0.3, 1.8, 2.0, 1.5)


def test_fractions_are_by_path_length():
    # Two segments of lengths 1 and 3: the quarter point is the end of the first.
    path = np.array(
        [[0, 0, 5, 0, 0, 0, 1, 1, 1], [1, 0, 5, 0, 0, 0, 1, 1, 1], [1, 3, 5, 0, 0, 0, 1, 1, 1]],
        dtype=float,
    )
    q = configurations_at_fractions(path, SPACE, np.array([0.0, 0.25, 0.5, 1.0]))
    np.testing.assert_allclose(q[:, :2], [[0, 0], [1, 0], [1, 1], [1, 3]], atol=1e-12)


def test_profile_matches_statics_at_the_samples(system, tmp_path):
    path = np.array([[0, 0, 5, 0, 0, 0, 1, 1, 1], [0, 0, 6, 0, 0.2, 0.5, 0.9, 1.1, 1.0]])
    profile = path_profile(system, SPACE, path, steps=10)
    assert profile.tension.shape == (11, 6) and profile.thrust.shape == (11, 3)
    report = evaluate_statics(system, path[1])
    np.testing.assert_allclose(profile.tension[-1], report.nominal_tension[0])
    # Hover at alpha = 1 by hand: each cable leaves the drone at elevation sin = h sin(1) / l
    # and leans inward by h cos(1) / l, h = sqrt(2^2 - 0.7^2); f0 = m g / (6 sin).
    h = np.sqrt(4.0 - 0.49)
    up, inward = h * np.sin(1.0) / 2.0, h * np.cos(1.0) / 2.0
    f0 = 1.5 * 9.81 / (6 * up)
    by_hand = np.hypot(9.81 + 2 * f0 * up, 2 * f0 * inward)
    assert profile.thrust[0, 0] == pytest.approx(by_hand, rel=1e-12)
    bands = plot_profile_bands({"T-RRT": [profile], "RRT": [profile]}, system, tmp_path / "b.png")
    single = plot_path_profile(profile, system, tmp_path / "p.png", title="demo")
    for png in (bands, single):
        assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_a_title_is_text_not_mathtext(system, tmp_path):
    """Issue 10, item 9: a task named like broken mathtext failed its task after planning."""
    path = np.array([[0, 0, 5, 0, 0, 0, 1, 1, 1], [1, 0, 5, 0, 0, 0, 1, 1, 1]], dtype=float)
    profile = path_profile(system, SPACE, path, steps=2)
    png = plot_path_profile(profile, system, tmp_path / "p.png", title=r"bridge $\frac{1}{$ 50%")
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_least_margins_at_the_benchmark_hover(system):
    """design.md section 5: at q = (0, 0, 5, 0, 0, 0, 1, 1, 1) f0 = 3.11 N, v = 1.18 N and
    m = 17.14 N, against f in [0.5, 30] N and h = 25 N."""
    hover = np.array([[0, 0, 5, 0, 0, 0, 1, 1, 1], [0, 0, 5, 0, 0, 0, 1, 1, 1]], dtype=float)
    margins = least_margins(path_profile(system, SPACE, hover, steps=4), system)
    assert margins.slack == pytest.approx(3.11 - 1.18 - 0.5, abs=0.01)
    assert margins.headroom == pytest.approx(30.0 - (3.11 + 1.18), abs=0.01)
    assert margins.thrust == pytest.approx(25.0 - 17.14, abs=0.01)
