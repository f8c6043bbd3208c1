"""Timed waypoints: shared times, straight legs that keep the load valid, and failure as status.

The load under straight legs is rebuilt here independently of the reducer's checks: drone
positions interpolated with ``np.interp`` at times ten times finer than the reducer's check
step, the platform solved with the direct kinematics, validity re-evaluated with the statics.
"""

from __future__ import annotations

import re

import numpy as np
import pytest

from flycrane.model.cable_system import CABLE_DRONE
from flycrane.model.direct_kinematics import configuration_from_drone_positions
from flycrane.model.kinematics import (
    drone_positions_from_configuration,
    platform_points_from_configuration,
)
from flycrane.model.statics import evaluate_statics
from missions.options import MissionOptions
from missions.trajectory.tracks import track_from_path
from missions.trajectory.waypoints import reduce_to_waypoints

ANGLES = [3, 5, 6, 7, 8]  # phi, sigma, alphas: unwrap before interpolating


def straight_leg_flight(track, plan, step):
    """Drones flying straight, constant-speed legs between the plan's waypoints, sampled every
    ``step`` s, and the planned configurations at the same times (dense track, linear)."""
    t = np.arange(0.0, track.duration, step)
    drones = np.empty((len(t), 3, 3))
    for j in range(3):
        for c in range(3):
            drones[:, j, c] = np.interp(t, plan.time, plan.drones[:, j, c])
    dense = track.q.copy()
    dense[:, ANGLES] = np.unwrap(dense[:, ANGLES], axis=0)
    planned = np.stack([np.interp(t, track.time, dense[:, c]) for c in range(9)], axis=1)
    return t, drones, planned


OPTIONS = {
    "defaults": MissionOptions(),
    "tight": MissionOptions(max_platform_deviation=0.01, max_cable_length_error=0.01),
    "short legs": MissionOptions(max_leg_duration=2.0),
}


@pytest.fixture(scope="module")
def plans(system, curved_track, feasible):
    return {
        name: reduce_to_waypoints(system, curved_track, feasible, options)
        for name, options in OPTIONS.items()
    }


@pytest.mark.parametrize("name", OPTIONS)
def test_waypoints_are_instants_of_the_track_shared_by_the_three_drones(
    system, curved_track, plans, name
):
    plan = plans[name]
    assert plan.ok, plan.reason
    assert plan.time.shape == (len(plan.indices),)
    assert plan.drones.shape == (len(plan.indices), 3, 3)
    assert plan.time[0] == 0.0 and plan.time[-1] == curved_track.duration
    assert np.all(np.diff(plan.time) > 0)
    # waypoint k of every drone is the same instant: the drones of one configuration
    np.testing.assert_array_equal(plan.time, curved_track.time[plan.indices])
    np.testing.assert_allclose(
        plan.drones, drone_positions_from_configuration(system, plan.q), atol=1e-12
    )
    assert np.diff(plan.time).max() <= OPTIONS[name].max_leg_duration


@pytest.mark.parametrize("name", OPTIONS)
def test_straight_legs_keep_the_load_valid_and_within_the_deviation_bounds(
    system, curved_track, plans, name
):
    plan, options = plans[name], OPTIONS[name]
    _, drones, planned = straight_leg_flight(curved_track, plan, options.check_resolution / 10)
    rebuilt = configuration_from_drone_positions(system, drones, initial=planned)
    assert rebuilt.converged.all()
    assert evaluate_statics(system, rebuilt.q).feasible.all()
    deviation = np.linalg.norm(rebuilt.q[:, :3] - planned[:, :3], axis=1)
    assert deviation.max() <= options.max_platform_deviation
    b = platform_points_from_configuration(system, planned)
    cable_error = np.abs(np.linalg.norm(drones[:, CABLE_DRONE] - b, axis=-1) - 2.0).max(axis=1)
    assert cable_error.max() <= options.max_cable_length_error
    # What the plan reports is what a finer look finds (to the fineness of its check step).
    assert plan.max_platform_deviation == pytest.approx(deviation.max(), rel=0.05)
    assert plan.max_cable_length_error == pytest.approx(cable_error.max(), rel=0.05)


def test_tighter_bounds_need_more_waypoints(plans):
    assert len(plans["tight"].time) > len(plans["defaults"].time)
    assert len(plans["short legs"].time) > len(plans["defaults"].time)


# P on a half circle of radius 2 m at z = 4 (a pure translation of the whole crane): every
# straight drone leg rebuilds the same platform shifted, so only a forbidden region matters.
ARC = np.array(
    [[2 * np.cos(a), 2 * np.sin(a), 4.0, 0.0, 0.0, 0.0, 1.0, 1.0, 1.0]
     for a in np.linspace(0.0, np.pi, 9)]
)  # fmt: skip
LOOSE = MissionOptions(max_platform_deviation=10.0, max_cable_length_error=10.0)


def forbid_platform_point(system, low, high):
    low, high = np.asarray(low), np.asarray(high)

    def validity(q):
        q = np.atleast_2d(q)
        inside = np.all((q[:, :3] > low) & (q[:, :3] < high), axis=1)
        return evaluate_statics(system, q).feasible & ~inside

    return validity


@pytest.fixture(scope="module")
def arc_track(system, space):
    assert evaluate_statics(system, ARC).feasible.all()
    return track_from_path(system, space, ARC, LOOSE)


def test_a_forbidden_region_on_the_chord_makes_the_reducer_add_waypoints(system, arc_track):
    nowhere = forbid_platform_point(system, [9] * 3, [10] * 3)
    free = reduce_to_waypoints(system, arc_track, nowhere, LOOSE)
    assert free.ok and len(free.time) == 2  # one leg: the chord through the circle's centre
    box_low, box_high = (-0.3, -0.3, 3.0), (0.3, 0.3, 5.0)  # around the centre, off the arc
    validity = forbid_platform_point(system, box_low, box_high)
    assert validity(ARC).all()
    plan = reduce_to_waypoints(system, arc_track, validity, LOOSE)
    assert plan.ok, plan.reason
    assert len(plan.time) > 2
    _, drones, planned = straight_leg_flight(arc_track, plan, 0.01)
    rebuilt = configuration_from_drone_positions(system, drones, initial=planned)
    assert rebuilt.converged.all()
    assert validity(rebuilt.q).all()
    # the free plan's single chord does cross the box: the test's premise
    _, drones, planned = straight_leg_flight(arc_track, free, 0.01)
    crossing = configuration_from_drone_positions(system, drones, initial=planned)
    assert not validity(crossing.q).all()


def test_an_invalid_path_ends_in_a_failed_status_with_a_reason(system, arc_track):
    """With the default deviation bound the legs must hug the path, so a box on the path
    cannot be flown around. (With LOOSE bounds a chord may legitimately skip it: what is
    checked is the flown load, and a chord that avoids the box is a valid flight.)"""
    on_the_arc = forbid_platform_point(system, (-0.3, 1.7, 3.0), (0.3, 2.3, 5.0))
    assert not on_the_arc(ARC[4]).all()  # the top of the half circle, (0, 2, 4)
    plan = reduce_to_waypoints(system, arc_track, on_the_arc, MissionOptions())
    assert plan.ok is False
    assert "no safe straight leg" in plan.reason
    # the leg it names touches the box: one of its two dense samples has P inside
    window = re.search(r"between ([0-9.]+) s and ([0-9.]+) s", plan.reason)
    t0, t1 = float(window[1]), float(window[2])
    inside = arc_track.time[~on_the_arc(arc_track.q)]
    assert np.any((inside >= t0 - 0.005) & (inside <= t1 + 0.005))
