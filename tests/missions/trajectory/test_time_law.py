"""The time law's pieces against profiles worked out by hand: the accelerations between
constant-speed segments, and a vertical leg's trapezoid and triangle."""

from __future__ import annotations

import numpy as np
import pytest

from missions.trajectory.time_law import segment_accelerations, vertical_profile


def test_segment_accelerations_on_a_hand_made_profile():
    # 1 m/s for 2 s then 3 m/s for 1 s: from rest over 1 s, +2 m/s over 1.5 s, to rest in 0.5 s
    result = segment_accelerations(np.array([1.0, 3.0]), np.array([2.0, 1.0]))
    np.testing.assert_allclose(result, [1.0, 2.0 / 1.5, -6.0])


@pytest.mark.parametrize(
    ("height", "expected"),
    [
        # 2 m at 0.5 m/s, 0.25 m/s^2: 2 s up to speed (0.5 m), 2 s cruising (1 m), 2 s braking
        (2.0, 6.0),
        # 0.25 m never reaches the speed: a triangle of 1 s up and 1 s down
        (0.25, 2.0),
    ],
)
def test_a_vertical_leg_is_the_hand_made_trapezoid_or_triangle(height, expected):
    t, travelled = vertical_profile(height, 0.5, 0.25, 0.1)
    assert t[0] == 0.0 and t[-1] == pytest.approx(expected)
    assert travelled[0] == 0.0 and travelled[-1] == pytest.approx(height)
    speed = np.diff(travelled) / np.diff(t)
    assert speed.min() >= 0.0 and speed.max() <= 0.5 + 1e-9
    # speeds up and brakes at no more than the acceleration (between segment midpoints)
    middle = (t[:-1] + t[1:]) / 2
    assert np.abs(np.diff(speed) / np.diff(middle)).max() <= 0.25 * (1 + 1e-6)
