"""The stream executor's targets against a trajectory in closed form: each drone at
constant acceleration, which the trajectory's cubic Hermite reproduces exactly."""

from __future__ import annotations

import numpy as np
import pytest

from missions.execution.group_clock import GroupClock
from missions.execution.options import ExecutionOptions
from missions.execution.stream import StreamExecutor
from missions.options import GeodeticOrigin
from missions.trajectory.drone_trajectory import DroneTrajectory

#: each drone's acceleration (ENU) [m/s^2]
ACCELERATION = np.array([[0.2, -0.1, 0.3], [0.0, 0.4, -0.2], [-0.3, 0.1, 0.1]])


class _Link:
    """A link nothing arrives on: the targets are computed, not sent."""

    def add_listener(self, *listener: object) -> None:
        pass


def _executor(lead: tuple[float, float] | None, speedup: float = 1.0) -> StreamExecutor:
    t = np.arange(0.0, 10.0 + 1e-9, 0.1)
    position = 0.5 * t[:, None, None] ** 2 * ACCELERATION
    trajectory = DroneTrajectory(
        time=t,
        position=position,
        velocity=t[:, None, None] * ACCELERATION,
        acceleration=np.broadcast_to(ACCELERATION, position.shape).copy(),
        homes=np.zeros((3, 3)),
    )
    links = [_Link(), _Link(), _Link()]
    executor = StreamExecutor(
        links,  # type: ignore[arg-type]
        trajectory,
        GeodeticOrigin(latitude=47.0, longitude=8.0, altitude=400.0),
        options=ExecutionOptions(lead=lead),
        speedup=speedup,
    )
    executor.clock = GroupClock(start=100.0, duration=10.0)
    return executor


@pytest.mark.parametrize("lead", [(0.05, 0.0), (0.12, 0.04), (0.0, 0.0)])
def test_targets_lead_the_present_by_the_horizontal_and_the_vertical_lead(lead):
    executor = _executor(lead)
    for k in range(3):
        p, v, a = executor._led(k, 103.0)
        across, up = 3.0 + lead[0], 3.0 + lead[1]
        expected_p = 0.5 * ACCELERATION[k] * np.array([across, across, up]) ** 2
        expected_v = ACCELERATION[k] * np.array([across, across, up])
        np.testing.assert_allclose(p, expected_p, atol=1e-12)
        np.testing.assert_allclose(v, expected_v, atol=1e-12)
        np.testing.assert_allclose(a, ACCELERATION[k], atol=1e-12)


def test_the_stream_leads_horizontally_by_default():
    horizontal, vertical = _executor(None).lead
    assert horizontal > vertical >= 0.0


@pytest.mark.parametrize("lead", [(-0.01, 0.0), (0.0, 0.5)])
def test_a_lead_out_of_range_is_refused_naming_the_field(lead):
    with pytest.raises(ValueError, match="lead"):
        ExecutionOptions(lead=lead)


@pytest.mark.parametrize(
    ("speedup", "lost_after"), [(1.0, 0.2), (2.0, 0.2), (3.0, 0.3), (5.0, 0.5), (10.0, 1.0)]
)
def test_a_lost_link_is_judged_on_a_tenth_of_a_second_of_wall_time_at_least(speedup, lost_after):
    """0.2 s of silence in real time (the aim); faster than real time a pause of the host
    is ``speedup`` times as long in the drones' time: at x10 a 0.06 s pause of the machine
    is 0.6 s of a simulator's silence."""
    monitor = _executor(None, speedup).monitor
    for k in range(3):
        monitor.heard(k, 100.0)
    assert monitor.faults(100.0 + lost_after - 0.01) == []
    assert {f.drone for f in monitor.faults(100.0 + lost_after + 0.01)} == {1, 2, 3}


@pytest.mark.parametrize("start_delay", [-0.1, 61.0])
def test_a_start_delay_out_of_range_is_refused_naming_the_field(start_delay):
    with pytest.raises(ValueError, match="start_delay"):
        ExecutionOptions(start_delay=start_delay)
