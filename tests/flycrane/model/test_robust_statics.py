"""The bound on the statics margins' fall against the exact direct kinematics and statics of
sampled drone errors, and the invariance it rests on."""

from __future__ import annotations

import numpy as np
import pytest

from flycrane.model.direct_kinematics import configuration_from_drone_positions
from flycrane.model.kinematics import drone_positions_from_configuration
from flycrane.model.robust_statics import MARGIN_NAMES, RobustStatics, margin_bounds, margins
from flycrane.model.statics import evaluate_statics
from tests.flycrane.model.sampling import feasible_configurations


@pytest.fixture(scope="module")
def configurations():
    """Feasible configurations of the Puzzle's space."""
    return feasible_configurations("puzzle", 11, 12)


def margins_for(system, q, drones):
    """The margins (S, 15) where the exact direct kinematics puts the platform for drones
    (S, 3, 3), solved from q."""
    solved = configuration_from_drone_positions(
        system, drones, initial=np.repeat(q[None], len(drones), 0)
    )
    assert solved.converged.all()
    return margins(evaluate_statics(system, solved.q))


def test_an_error_the_drones_share_leaves_every_margin_as_it_is(configurations):
    """Gravity is the only load: the three drones moved 0.3 m east, 0.2 m south and 0.1 m
    up move the platform with them and change no tension or thrust."""
    system, qs = configurations
    drones = drone_positions_from_configuration(system, qs)
    for q, a in zip(qs, drones, strict=True):
        moved = margins_for(system, q, (a + [0.3, -0.2, 0.1])[None])[0]
        np.testing.assert_allclose(moved, margins(evaluate_statics(system, q[None]))[0],
                                   atol=1e-6)  # fmt: skip


def test_the_bound_covers_sampled_errors_and_is_not_loose(configurations):
    """Each drone's own error at the corners of its bounds (its horizontal radius in a
    random direction, a vertical bound), solved exactly: no margin falls by more than its
    bound and the second-order term (which took the worst of 300 samples to 0.96-1.14x
    of the bound on these 12 configurations), and the worst sample reaches at least half
    of it."""
    system, qs = configurations
    own = (0.03, 0.02)
    rng = np.random.default_rng(2)
    bounds = margin_bounds(system, qs, own)
    nominal = margins(evaluate_statics(system, qs))
    worst = []
    for q, a, bound, m in zip(qs, drone_positions_from_configuration(system, qs), bounds,
                              nominal, strict=True):  # fmt: skip
        angle = rng.uniform(0, 2 * np.pi, (300, 3))
        errors = np.stack([own[0] * np.cos(angle), own[0] * np.sin(angle),
                           own[1] * rng.choice([-1.0, 1.0], (300, 3))], axis=-1)  # fmt: skip
        fall = m - margins_for(system, q, a[None] + errors)
        assert np.all(fall <= bound * 1.2 + 1e-3), (fall.max(0), bound)
        worst.append(np.max(fall.max(0) / bound))
    assert np.median(worst) > 0.5


def test_the_least_robust_margin_is_named():
    margin = np.full((3, 15), 2.0)
    bound = np.full((3, 15), 0.5)
    bound[2, 13] = 2.25
    least = RobustStatics(margin, bound).least()
    assert least == (pytest.approx(-0.25), "thrust of drone 2", 2)
    assert MARGIN_NAMES[4] == "slack of cable 5"
