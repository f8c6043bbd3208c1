"""The cost of eq. 8: infinite exactly off the feasible set, finite and continuous on it."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from flycrane.model.cable_system import CableSystem
from flycrane.model.cost import CostForm, cost_from_report
from flycrane.model.statics import evaluate_statics
from flycrane.model.statics_kernel import configuration_cost
from tests.conftest import random_configurations

configurations = st.tuples(
    st.floats(-20, 20),
    st.floats(-20, 20),
    st.floats(1, 30),
    st.floats(-np.pi, np.pi),
    st.floats(0, 1.0),
    st.floats(-np.pi, np.pi),
    st.floats(0.2, 2.0),
    st.floats(0.2, 2.0),
    st.floats(0.2, 2.0),
)

SYSTEM = CableSystem.from_spec()


@given(configurations)
@settings(max_examples=300)
def test_cost_is_infinite_exactly_where_a_margin_is_not_positive(q):
    report = evaluate_statics(SYSTEM, np.array(q))
    margins = np.concatenate(
        [report.slack_margin[0], report.overload_margin[0], report.thrust_margin[0]]
    )
    for form in CostForm:
        cost = cost_from_report(SYSTEM, report, form)[0]
        compiled = configuration_cost(SYSTEM, np.array(q), form)[0]
        if report.singular[0] or np.any(margins <= 0):
            assert cost == np.inf and compiled == np.inf
        else:
            assert 0 < cost < np.inf
            assert compiled == pytest.approx(cost, rel=1e-9)


@given(configurations, st.integers(0, 8), st.floats(-1.0, 1.0))
@settings(max_examples=300)
def test_cost_is_continuous_inside_the_feasible_set(q, axis, direction):
    q = np.array(q)
    c0 = configuration_cost(SYSTEM, q)[0]
    if not np.isfinite(c0):
        return
    step = np.zeros(9)
    step[axis] = 1e-7 * (abs(direction) if axis == 4 else direction)  # tilt stays >= 0
    c1 = configuration_cost(SYSTEM, q + step)[0]
    # A 1e-7 step moves a margin by ~1e-7 N: the cost changes by a small relative amount,
    # unless the configuration sits within ~1e-5 N of a bound (then c0 is astronomical).
    if c0 < 1e20:
        assert c1 == pytest.approx(c0, rel=1e-3)


def test_normalized_cost_is_the_product_of_fifteen_relative_margins(system):
    report = evaluate_statics(system, [0, 0, 5, 0, 0, 0, 1, 1, 1])
    # Hand computation with design.md's rounded values: slack (1.93 - 0.5) / 29.5,
    # overload (30 - 4.29) / 29.5, thrust (25 - 17.14) / 25.
    by_hand = 1.0 / (((1.93 - 0.5) / 29.5) ** 6 * ((30 - 4.29) / 29.5) ** 6 * (7.86 / 25) ** 3)
    assert cost_from_report(system, report)[0] == pytest.approx(by_hand, rel=0.02)
    raw = 1.0 / ((1.93 - 0.5) ** 6 * (30 - 4.29) ** 6 * 7.86**3)
    assert cost_from_report(system, report, CostForm.RAW)[0] == pytest.approx(raw, rel=0.02)


def test_cost_grows_without_bound_towards_the_slack_boundary(system):
    # alpha = 1 is feasible, alpha = 1.4 is not (design.md): bisect to the boundary.
    lo, hi = 1.0, 1.4
    q = lambda a: [0, 0, 5, 0, 0, 0, a, a, a]  # noqa: E731
    for _ in range(60):
        mid = (lo + hi) / 2
        lo, hi = (mid, hi) if np.isfinite(configuration_cost(system, q(mid))[0]) else (lo, mid)
    approach = lo - np.geomspace(1e-2, 1e-12, 11)
    costs = configuration_cost(system, np.array([q(a) for a in approach]))
    assert np.all(np.isfinite(costs))
    assert np.all(np.diff(costs) > 0)
    assert costs[-1] > 1e6 * costs[0]


def test_batch_and_single_evaluations_agree(system):
    q = random_configurations(np.random.default_rng(20), 500)
    batch = configuration_cost(system, q)
    single = np.array([configuration_cost(system, row)[0] for row in q])
    np.testing.assert_array_equal(batch, single)
