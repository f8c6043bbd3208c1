"""The shared time law: quasi-static limits, rest to rest, and analytic durations.

Speeds, angular rates and accelerations are measured here by plain finite differences of the
dense track (drone positions, and scipy's rotation angles between consecutive orientations),
not with the module's own helpers; durations are compared with the analytic trapezoid
(and triangle) profiles of a point moving on a line.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from flycrane.model.kinematics import drone_positions_from_configuration, matrix_from_tilt_torsion
from flycrane.model.statics import evaluate_statics
from missions.options import MissionOptions
from missions.trajectory.time_law import segment_accelerations
from missions.trajectory.tracks import track_from_path
from tests.missions.conftest import CURVED_PATH

HOVER = [0.0, 0.0, 3.0, 0.0, 0.0, 0.0, 1.0, 1.0, 1.0]

PATHS = {
    "curved": CURVED_PATH,
    # right-angle corners: east, then up, then north with a small yaw
    "corners": np.array(
        [
            [0, 0, 2, 0, 0, 0, 1, 1, 1],
            [2, 0, 2, 0, 0, 0, 1, 1, 1],
            [2, 0, 4, 0, 0, 0, 1, 1, 1],
            [2, 1.5, 4, 0, 0, 0.5, 1, 1, 1],
        ],
        dtype=float,
    ),
    # a pure yaw: every drone on a circle, the angular-rate limit binds
    "yaw": np.array([HOVER, [0, 0, 3, 0, 0, np.pi / 2, 1, 1, 1]], dtype=float),
    # the alphas alone: drones swing about their edges, the platform only sinks or rises
    "alphas": np.array([HOVER, [0, 0, 3, 0, 0, 0, 0.8, 1.2, 1.0]], dtype=float),
}

LIMITS = {
    "defaults": MissionOptions(),
    "fast but gentle": MissionOptions(max_drone_speed=1.0, max_acceleration=0.1),
    "slow turns": MissionOptions(max_angular_rate=0.05),
    "brisk": MissionOptions(max_drone_speed=2.0, max_angular_rate=1.0, max_acceleration=2.0),
}


def measured(track):
    """Drone speeds (K-1, 3), platform angular rates (K-1,), and drone accelerations (K, 3)
    between segments (from rest before the first, to rest after the last)."""
    dt = np.diff(track.time)
    speeds = np.linalg.norm(np.diff(track.drones, axis=0), axis=-1) / dt[:, None]
    rotations = Rotation.from_matrix(matrix_from_tilt_torsion(track.q[:, 3:6]))
    rates = (rotations[:-1].inv() * rotations[1:]).magnitude() / dt
    # Each segment's constant speed lives at its mid time; rest at the track's two ends.
    mid = np.concatenate([[0.0], (track.time[:-1] + track.time[1:]) / 2, [track.duration]])
    padded = np.concatenate([np.zeros((1, 3)), speeds, np.zeros((1, 3))])
    accelerations = np.diff(padded, axis=0) / np.diff(mid)[:, None]
    return speeds, rates, accelerations


@pytest.fixture(scope="module")
def tracks(system, space):
    for name, path in PATHS.items():
        assert evaluate_statics(system, path).feasible.all(), name
    return {
        (p, o): track_from_path(system, space, PATHS[p], LIMITS[o]) for p in PATHS for o in LIMITS
    }


@pytest.mark.parametrize("limits", LIMITS)
@pytest.mark.parametrize("path", PATHS)
def test_time_law_keeps_every_drone_speed_angular_rate_and_acceleration_within_limits(
    tracks, path, limits
):
    track, options = tracks[path, limits], LIMITS[limits]
    speeds, rates, accelerations = measured(track)
    slack = 1 + 1e-6  # the sweeps stop at a relative change of 1e-9
    assert speeds.max() <= options.max_drone_speed * slack
    assert rates.max() <= options.max_angular_rate * slack
    assert np.abs(accelerations).max() <= options.max_acceleration * slack
    # The module's own helper reads the same grid the same way.
    own = segment_accelerations(speeds, np.diff(track.time))
    np.testing.assert_allclose(own, accelerations, rtol=1e-9, atol=1e-12)
    # ...and some limit is reached: the law is not needlessly slow.
    assert max(
        speeds.max() / options.max_drone_speed,
        rates.max() / options.max_angular_rate,
        np.abs(accelerations).max() / options.max_acceleration,
    ) == pytest.approx(1.0, rel=1e-6)


@pytest.mark.parametrize("limits", LIMITS)
@pytest.mark.parametrize("path", PATHS)
def test_track_starts_and_ends_at_rest(tracks, path, limits):
    track, options = tracks[path, limits], LIMITS[limits]
    speeds, _, _ = measured(track)
    steps = np.linalg.norm(np.diff(track.drones, axis=0), axis=-1).max(axis=1)
    # From rest, a drone accelerating at most a over a segment of length s reaches at most
    # sqrt(2 a s); half a segment's time at the start (the grid's reading) allows less still.
    for segment in (0, -1):
        bound = np.sqrt(options.max_acceleration * steps[segment])
        assert speeds[segment].max() <= bound
        assert speeds[segment].max() < 0.3 * options.max_drone_speed


@pytest.mark.parametrize("path", PATHS)
def test_track_time_is_strictly_increasing_from_zero_and_follows_the_path(system, tracks, path):
    track = tracks[path, "defaults"]
    assert track.time[0] == 0.0
    assert np.all(np.diff(track.time) > 0)
    np.testing.assert_allclose(track.q[0], PATHS[path][0], atol=1e-12)
    np.testing.assert_allclose(
        drone_positions_from_configuration(system, track.q[-1]),
        drone_positions_from_configuration(system, PATHS[path][-1]),
        atol=1e-9,
    )
    np.testing.assert_allclose(
        track.drones, drone_positions_from_configuration(system, track.q), atol=1e-12
    )


@pytest.mark.parametrize("path", PATHS)
@pytest.mark.parametrize(
    "raised",
    [
        {"max_drone_speed": 1.0},
        {"max_angular_rate": 0.5},
        {"max_acceleration": 0.5},
        {"max_drone_speed": 0.7, "max_angular_rate": 0.3, "max_acceleration": 0.4},
    ],
    ids=["speed", "angular rate", "acceleration", "all three"],
)
def test_raising_a_limit_never_makes_the_track_slower(system, space, tracks, path, raised):
    base = tracks[path, "defaults"]
    faster = track_from_path(system, space, PATHS[path], MissionOptions(**raised))
    assert faster.duration <= base.duration * (1 + 1e-9)


@pytest.mark.parametrize(
    ("length", "speed", "acceleration", "expected"),
    [
        # trapezoid: cruise at v, ramps of v / a at each end: L / v + v / a
        (3.0, 0.5, 0.25, 3.0 / 0.5 + 0.5 / 0.25),
        (3.0, 0.5, 1.0, 3.0 / 0.5 + 0.5 / 1.0),
        (2.0, 0.3, 0.25, 2.0 / 0.3 + 0.3 / 0.25),
        # triangle: v is never reached (v^2 / a > L): 2 sqrt(L / a)
        (1.0, 1.0, 0.25, 2.0 * np.sqrt(1.0 / 0.25)),
    ],
)
def test_vertical_lift_takes_the_analytic_trapezoid_duration(
    system, space, length, speed, acceleration, expected
):
    path = np.array([HOVER, HOVER])
    path[1, 2] += length
    options = MissionOptions(max_drone_speed=speed, max_acceleration=acceleration)
    track = track_from_path(system, space, path, options)
    assert track.duration == pytest.approx(expected, rel=0.01)
    # Every drone climbs exactly as far as the platform.
    np.testing.assert_allclose(track.drones[-1] - track.drones[0], [[0, 0, length]] * 3, atol=1e-12)


def test_pure_yaw_is_timed_by_the_angular_rate(system, space):
    """Yaw by pi/2 at w_max: each drone runs on a circle of radius r at w r < v_max, and
    its ramps at a take w r / a; so the duration is (pi/2) / w + w r / a."""
    options = MissionOptions(max_angular_rate=0.2, max_acceleration=0.25)
    s, cable, alpha = 1.4, 2.0, 1.0
    # a drone's distance from the vertical axis through P (design.md s.4, octahedral preset)
    radius = s / (2 * np.sqrt(3)) + np.sqrt(cable**2 - (s / 2) ** 2) * np.cos(alpha)
    assert 0.2 * radius < options.max_drone_speed
    track = track_from_path(system, space, PATHS["yaw"], options)
    expected = (np.pi / 2) / 0.2 + 0.2 * radius / 0.25
    assert track.duration == pytest.approx(expected, rel=0.005)
