"""Per-waypoint annotations against the design's worked example and force balance."""

from __future__ import annotations

import json

import numpy as np
import pytest

from missions.trajectory.annotations import annotate

HOVER = [0.0, 0.0, 5.0, 0.0, 0.0, 0.0, 1.0, 1.0, 1.0]


def test_hover_annotations_are_the_worked_example_of_the_design(system):
    """design.md s.5: f0 = 3.11 N, v = 1.18 N, m_k = 17.14 N at the hover pose."""
    a = annotate(system, [12.5], [HOVER])
    assert a.time.tolist() == [12.5]
    np.testing.assert_allclose(a.tension, 3.11, atol=0.01)
    np.testing.assert_allclose(a.tension_low, 3.11 - 1.18, atol=0.01)
    np.testing.assert_allclose(a.tension_high, 3.11 + 1.18, atol=0.01)
    np.testing.assert_allclose(a.thrust_bound, 17.14, atol=0.01)
    np.testing.assert_allclose(a.thrust_margin, 25.0 - 17.14, atol=0.01)
    assert np.isfinite(a.cost).all() and a.cost[0] > 1.0


def test_drone_thrusts_carry_the_whole_weight(system, curved_flight):
    """Force balance of the whole crane: the three nominal thrusts add up to the weight of
    the platform (1.5 kg) and the three drones (1 kg each), straight up, at every waypoint."""
    a = annotate(system, curved_flight.time, curved_flight.q)
    total = a.thrust.sum(axis=1)
    np.testing.assert_allclose(total, np.tile([0.0, 0.0, 4.5 * 9.81], (len(total), 1)), atol=1e-9)
    np.testing.assert_allclose(a.thrust_magnitude, np.linalg.norm(a.thrust, axis=-1))
    assert np.all(a.thrust_bound >= a.thrust_magnitude - 1e-12)  # worst case >= nominal
    np.testing.assert_allclose(a.thrust_margin, 25.0 - a.thrust_bound)


def test_records_are_plain_json_with_infinite_values_as_null(system):
    slack = [0.0, 0.0, 5.0, 0.0, 0.0, 0.0, 1.4, 1.4, 1.4]  # a cable goes slack (design s.5)
    records = annotate(system, [0.0, 1.0], [HOVER, slack]).records()
    text = json.dumps(records, allow_nan=False)
    back = json.loads(text)
    assert [r["waypoint"] for r in back] == [0, 1]
    assert back[1]["cost"] is None
    assert back[0]["cost"] == pytest.approx(annotate(system, [0.0], [HOVER]).cost[0])
    assert [d["drone"] for d in back[0]["drones"]] == [1, 2, 3]
    assert [c["cable"] for c in back[0]["cables"]] == [1, 2, 3, 4, 5, 6]
    assert back[0]["cables"][0]["tension"] == pytest.approx(3.11, abs=0.01)
    assert len(back[0]["drones"][0]["thrust"]) == 3
