"""Drone trajectories: on the plan's path, velocity and acceleration the derivatives of
their positions, within the speed and acceleration limits also at a corner (closed-form
corner speed), and the set-down leg a rest-to-rest descent of its height."""

from __future__ import annotations

import numpy as np
import pytest

from missions.options import MissionOptions
from missions.trajectory.drone_trajectory import DroneTrajectory
from missions.trajectory.tracks import Track
from missions.trajectory.vertical_legs import VerticalLeg

OPTIONS = MissionOptions()
STEP = 0.02  # the dense track's spacing [m]


def l_track() -> Track:
    """Three drones on parallel L-shaped paths (4 m east, a 90 degree corner, 4 m north),
    a dense sample every 2 cm; the configurations only need a level platform."""
    east = np.arange(0.0, 4.0 + STEP / 2, STEP)
    north = np.arange(STEP, 4.0 + STEP / 2, STEP)
    path = np.concatenate(
        [np.column_stack([east, 0 * east]), np.column_stack([0 * north + 4.0, north])]
    )
    drones = np.stack(
        [np.column_stack([path + [k, 2 * k], np.full(len(path), 5.0)]) for k in range(3)], axis=1
    )
    return Track(np.zeros(len(path)), np.zeros((len(path), 9)), drones)


def distance_to_polyline(points: np.ndarray, polyline: np.ndarray) -> np.ndarray:
    a, b = polyline[:-1], polyline[1:]
    ab = b - a
    s = np.clip(np.einsum("nsa,sa->ns", points[:, None] - a, ab) / np.einsum("sa,sa->s", ab, ab),
                0, 1)  # fmt: skip
    nearest = a + s[..., None] * ab
    return np.linalg.norm(points[:, None] - nearest, axis=-1).min(axis=1)


def test_positions_lie_on_the_plan_and_derivatives_follow_them():
    track = l_track()
    trajectory = DroneTrajectory.of_plan(track, OPTIONS)
    task = trajectory.in_task_frame(trajectory.position)
    for k in range(3):
        assert distance_to_polyline(task[:, k], track.drones[:, k]).max() < 1e-9
    # velocity: the central difference of positions read between samples
    tau = np.linspace(0.5, trajectory.duration - 0.5, 400)
    h = 1e-3
    ahead, behind = trajectory.at(tau + h)[0], trajectory.at(tau - h)[0]
    np.testing.assert_allclose(trajectory.at(tau)[1], (ahead - behind) / (2 * h), atol=0.02)
    # homes: below the start, home_height up
    np.testing.assert_allclose(trajectory.homes[:, 2], OPTIONS.home_height)
    np.testing.assert_allclose(trajectory.homes[:, :2], track.drones[0, :, :2])


def test_speed_and_acceleration_stay_within_the_limits_also_at_the_corner():
    trajectory = DroneTrajectory.of_plan(l_track(), OPTIONS)
    speed = np.linalg.norm(trajectory.velocity, axis=-1)
    assert speed.max() <= OPTIONS.max_drone_speed * 1.01
    # the corner's turn is one point of the path: its smoothed second derivative peaks at
    # less than half again the limit it keeps on average
    assert np.linalg.norm(trajectory.acceleration, axis=-1).max() <= 1.5 * OPTIONS.max_acceleration
    # at the corner the turn 2 v sin(45 deg) must fit a l over the 2 cm around it
    corner = np.argmin(np.linalg.norm(trajectory.in_task_frame(trajectory.position)[:, 0]
                                      - [4.0, 0.0, 5.0], axis=-1))  # fmt: skip
    bound = np.sqrt(OPTIONS.max_acceleration * STEP / (2 * np.sin(np.pi / 4)))
    assert speed[corner, 0] <= bound * 1.05
    # from rest, to rest
    assert np.allclose(trajectory.velocity[[0, -1]], 0.0)


def test_from_rest_a_drone_speeds_up_before_it_moves_and_brakes_into_the_hold():
    """The track leaves east from rest and arrives north at rest: over its first and last
    0.4 s the acceleration never points against the motion (a drone told to brake before
    it has moved lags its start)."""
    trajectory = DroneTrajectory.of_plan(l_track(), OPTIONS)
    n = int(0.4 / trajectory.step)
    assert (trajectory.acceleration[:n, :, 0] >= 0.0).all()
    assert (trajectory.acceleration[-n:, :, 1] <= 0.0).all()
    assert (trajectory.velocity[:n, :, 0] >= 0.0).all()


def test_reading_between_samples_holds_at_the_end():
    trajectory = DroneTrajectory.of_plan(l_track(), OPTIONS)
    p, v, a = trajectory.at(trajectory.duration + 100.0)
    assert np.allclose(v, 0.0) and np.allclose(a, 0.0)
    np.testing.assert_allclose(p, trajectory.position[-1])


def test_a_set_down_descends_its_height_from_rest_to_rest_within_the_leg_speed():
    track = l_track()
    end = track.q[-1].copy()
    leg = VerticalLeg(end - [0, 0, 0.3, 0, 0, 0, 0, 0, 0], end, ("roof",))
    trajectory = DroneTrajectory.of_plan(track, OPTIONS, set_down=leg)
    z = trajectory.in_task_frame(trajectory.position)[:, :, 2]
    assert z[-1] == pytest.approx(z[0] - 0.3, abs=1e-9)
    climb = np.diff(z, axis=0) / trajectory.step
    assert climb.min() >= -OPTIONS.vertical_leg_speed - 1e-9
    assert trajectory.set_down_start is not None
    assert (trajectory.time > trajectory.set_down_start).any()
    assert np.allclose(trajectory.velocity[-1], 0.0)


def test_the_nearest_time_is_where_a_drone_at_constant_speed_passes_the_position():
    """Drone 1 flies east at 0.5 m/s from its home (2, 0, 0); the plan time it passes a
    position is its distance over the speed, looked for only within the window."""
    time = np.arange(0.0, 10.0 + 1e-9, 0.1)
    position = np.zeros((len(time), 3, 3))
    position[:, 1, 0] = 0.5 * time
    velocity = np.zeros_like(position)
    velocity[:, 1, 0] = 0.5
    homes = np.array([[0.0, 0.0, 0.0], [2.0, 0.0, 0.0], [0.0, 4.0, 0.0]])
    trajectory = DroneTrajectory(time, position, velocity, np.zeros_like(position), homes)
    here = np.array([2.0 + 1.5, 0.03, 0.0])  # 3 s along, a little off the path
    assert trajectory.nearest_time(1, here, 4.0, 3.0) == pytest.approx(3.0, abs=0.011)
    assert trajectory.nearest_time(1, here, 7.0, 2.0) == pytest.approx(5.0, abs=0.011)
    assert trajectory.nearest_time(1, here + [10.0, 0, 0], 9.0, 3.0) == pytest.approx(10.0)
