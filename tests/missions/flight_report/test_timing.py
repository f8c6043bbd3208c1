"""Start and end delays of a clocked flight against closed-form motions: each drone flown
as its model shifted in time by a known delay, with a steady offset, at a log's rate."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from missions.flight_report.timing import arrivals, end_delays, motion_end, start_delays
from missions.trajectory.motion import DroneMotion

#: each drone's delay [s] and steady offset [m]
DELAYS = (0.0, 0.04, 0.09)
OFFSET = np.array([[0.01, -0.02, 0.005], [0.0, 0.015, -0.01], [-0.02, 0.0, 0.01]])
DURATION = 10.0


def _smooth(u: np.ndarray) -> np.ndarray:
    """0 -> 1 over u in [0, 1] with zero velocity at both ends (a quintic)."""
    u = np.clip(u, 0.0, 1.0)
    return u**3 * (10 - 15 * u + 6 * u**2)


def _plan() -> SimpleNamespace:
    t = np.arange(0.0, DURATION + 3.0 + 1e-9, 0.01)  # the motion, then 3 s at rest
    direction = np.array([[1.0, 0.5, -0.3], [0.2, 1.0, 0.1], [-0.6, 0.4, -0.5]])
    drones = _smooth(t / DURATION)[:, None, None] * direction
    motion = DroneMotion(t, drones, np.array([0.0, DURATION]))
    return SimpleNamespace(motion=motion, drones_at=motion.at, mode="stream", end_seq=(9, 9, 9))


def _vehicles(plan: SimpleNamespace) -> list[SimpleNamespace]:
    t = np.arange(-2.0, DURATION + 3.0, 0.02)  # a 50 Hz log from 2 s before the start
    return [
        SimpleNamespace(
            estimated=SimpleNamespace(time=t, enu=plan.drones_at(t - delay)[:, k] + OFFSET[k])
        )
        for k, delay in enumerate(DELAYS)
    ]


RELEASES = SimpleNamespace(mission_time=lambda k, time: time)


def test_the_motion_ends_where_the_model_comes_to_rest():
    assert motion_end(_plan()) == pytest.approx(DURATION, abs=0.011)


def test_start_and_end_delays_are_the_imposed_shifts_whatever_the_steady_offset():
    plan = _plan()
    vehicles = _vehicles(plan)
    np.testing.assert_allclose(start_delays(plan, vehicles, RELEASES), DELAYS, atol=0.004)
    np.testing.assert_allclose(end_delays(plan, vehicles, RELEASES), DELAYS, atol=0.004)


def test_a_clocked_flight_arrives_when_its_shifted_model_does():
    """Not when it first comes within a threshold of its end: the last centimetres of a
    smooth stop take a large part of a second."""
    plan = _plan()
    arrived = arrivals(plan, _vehicles(plan), RELEASES)  # type: ignore[arg-type]
    np.testing.assert_allclose(arrived, DURATION + np.array(DELAYS), atol=0.015)
