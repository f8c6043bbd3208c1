"""Shared hand-made paths for the mission-generation tests (default benchmark system).

Every path here is checked feasible configuration by configuration with the statics; the
validity used by default is statics feasibility alone (no scene), so the tests exercise the
mission code, not the collision layer.
"""

from __future__ import annotations

import numpy as np
import pytest

from flycrane.model.cable_system import CableSystem
from flycrane.model.statics import evaluate_statics
from flycrane.planning.state_space import ConfigurationSpace
from missions.options import MissionOptions
from missions.trajectory.flight_plan import FlightPlan, plan_flight
from missions.trajectory.tracks import Track, track_from_path
from missions.trajectory.waypoints import WaypointPlan, reduce_to_waypoints

#: A lift with a tilt, a yaw of 90 degrees and unequal alphas on the way: curved drone tracks.
CURVED_PATH = np.array(
    [
        [0.0, 0.0, 2.0, 0.0, 0.0, 0.0, 1.0, 1.0, 1.0],
        [0.0, 0.0, 4.0, 0.0, 0.1, 0.8, 1.0, 0.95, 1.05],
        [1.0, 0.0, 6.0, 0.0, 0.0, np.pi / 2, 1.0, 1.0, 1.0],
    ]
)


def statics_validity(system: CableSystem):
    """Validity = wrench- and thrust-feasibility of the statics (design.md s.5)."""
    return lambda q: evaluate_statics(system, q).feasible


@pytest.fixture(scope="session")
def space(system: CableSystem) -> ConfigurationSpace:
    return ConfigurationSpace.for_system(system, (-10, -10, 0), (10, 10, 20), 0.5, 0.5, 1.4)


@pytest.fixture(scope="session")
def feasible(system: CableSystem):
    return statics_validity(system)


@pytest.fixture(scope="session")
def curved_track(system: CableSystem, space: ConfigurationSpace) -> Track:
    assert evaluate_statics(system, CURVED_PATH).feasible.all()
    return track_from_path(system, space, CURVED_PATH, MissionOptions())


@pytest.fixture(scope="session")
def curved_plan(system: CableSystem, curved_track: Track, feasible) -> WaypointPlan:
    """The fewest waypoints whose straight legs keep the load feasible."""
    plan = reduce_to_waypoints(system, curved_track, feasible, MissionOptions())
    assert plan.ok, plan.reason
    return plan


@pytest.fixture(scope="session")
def curved_flight(system: CableSystem, curved_track: Track, feasible) -> FlightPlan:
    """The flyable plan of the curved path: timed spline waypoints and their motion."""
    plan = plan_flight(system, curved_track, feasible, MissionOptions())
    assert plan.ok, plan.reason
    return plan
