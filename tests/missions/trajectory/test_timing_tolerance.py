"""Timing tolerance: the reported limits are the edge between safe and unsafe flights.

Flights with a late start or a mismatched speed are replayed with clock functions written
here, through ``flight_is_safe`` and through an independent replay (each drone's commanded
positions, ``np.interp`` at 0.01 s on its own clock, direct kinematics, statics), five to
ten times finer than the module's step.
"""

from __future__ import annotations

import re
from itertools import combinations

import numpy as np
import pytest

from flycrane.model.cable_system import CableSystem
from flycrane.model.direct_kinematics import configuration_from_drone_positions
from flycrane.model.statics import evaluate_statics
from flycrane.model.system_spec import Perturbation, SystemSpec
from missions.options import MissionOptions
from missions.trajectory.timing_tolerance import (
    TOLERANCE_RESOLUTION,
    flight_is_safe,
    timing_tolerance,
)
from tests.missions.conftest import CURVED_PATH, statics_validity

ANGLES = [3, 5, 6, 7, 8]
CASES = [late for n in (1, 2) for late in combinations(range(3), n)]  # who starts late
OPTIONS = MissionOptions()


def late_start(offset, late):
    mask = np.isin(np.arange(3), late)
    return lambda t: t[:, None] - offset * mask


def mismatched_speed(fraction, drone):
    """``fraction`` > 0: the drone runs faster, < 0 slower."""
    factor = 1.0 + fraction * (np.arange(3) == drone)
    return lambda t: t[:, None] * factor


def replay_is_safe(system, track, plan, clock, step=0.01):
    """The flight replayed without the module: drones hold their start until their clock
    reaches 0 and their last position after it, and follow their commanded motion between."""
    end = plan.duration
    t = np.arange(0.0, 2 * end + step, step)
    local = np.clip(clock(t), 0.0, end)
    motion = plan.motion
    drones = np.stack(
        [np.stack([np.interp(local[:, j], motion.time, motion.drones[:, j, c]) for c in range(3)],
                  axis=-1) for j in range(3)],
        axis=1,
    )  # fmt: skip
    dense = track.q.copy()
    dense[:, ANGLES] = np.unwrap(dense[:, ANGLES], axis=0)
    mean = np.interp(local.mean(axis=1), plan.time, plan.track_time)
    initial = np.stack([np.interp(mean, track.time, dense[:, c]) for c in range(9)], axis=1)
    rebuilt = configuration_from_drone_positions(system, drones, initial=initial)
    return bool(np.all(rebuilt.converged & evaluate_statics(system, rebuilt.q).feasible))


@pytest.fixture(scope="module")
def tolerance(system, curved_track, curved_flight, feasible):
    return timing_tolerance(system, curved_track, curved_flight, feasible, OPTIONS)


def test_the_plan_as_timed_is_safe_and_a_large_offset_is_not(
    system, curved_track, curved_flight, feasible
):
    on_time = late_start(0.0, ())
    assert flight_is_safe(system, curved_track, curved_flight, feasible, on_time,
                          OPTIONS.check_resolution)  # fmt: skip
    assert replay_is_safe(system, curved_track, curved_flight, on_time)
    assert not replay_is_safe(system, curved_track, curved_flight, late_start(3.0, (0,)))


def test_start_offset_just_below_the_tolerance_is_safe_and_just_above_is_not(
    system, curved_track, curved_flight, feasible, tolerance
):
    offset = tolerance.start_offset
    assert 0.0 < offset < tolerance.searched_offset
    named = tuple(int(d) - 1 for d in re.findall(r"\d", tolerance.start_offset_case))
    assert named in CASES and tolerance.start_offset_case.endswith("late")
    step = OPTIONS.check_resolution
    for late in CASES:  # every case survives the reported offset...
        clock = late_start(offset, late)
        assert flight_is_safe(system, curved_track, curved_flight, feasible, clock, step), late
        assert replay_is_safe(system, curved_track, curved_flight, clock), late
    # ...and the named one fails just beyond it (one bisection bracket, 5 ms, further)
    above = offset + 2 * TOLERANCE_RESOLUTION * tolerance.searched_offset
    clock = late_start(above, named)
    assert not flight_is_safe(system, curved_track, curved_flight, feasible, clock, step)
    assert not replay_is_safe(system, curved_track, curved_flight, clock)


def test_speed_mismatch_just_below_the_tolerance_is_safe_and_just_above_is_not(
    system, curved_track, curved_flight, feasible, tolerance
):
    mismatch = tolerance.speed_mismatch
    assert 0.0 < mismatch < tolerance.searched_mismatch
    drone, word = re.fullmatch(
        r"drone (\d) (faster|slower)", tolerance.speed_mismatch_case
    ).groups()
    sign = 1.0 if word == "faster" else -1.0
    step = OPTIONS.check_resolution
    for j in range(3):
        for s in (1.0, -1.0):
            clock = mismatched_speed(s * mismatch, j)
            assert flight_is_safe(system, curved_track, curved_flight, feasible, clock, step)
            assert replay_is_safe(system, curved_track, curved_flight, clock)
    above = mismatch + 2 * TOLERANCE_RESOLUTION * tolerance.searched_mismatch
    clock = mismatched_speed(sign * above, int(drone) - 1)
    assert not flight_is_safe(system, curved_track, curved_flight, feasible, clock, step)
    assert not replay_is_safe(system, curved_track, curved_flight, clock)


def test_more_statics_margin_never_gives_less_tolerance(
    system, curved_track, curved_flight, tolerance
):
    """A smaller perturbation ellipsoid and wider tension and thrust limits make every
    feasible configuration of the default system feasible (nested feasible sets), so the
    same flights can only stay safe longer. (A lighter platform is *not* such a margin: it
    lowers the nominal tensions towards slack, and CURVED_PATH becomes infeasible at 1 kg.)"""
    roomy = CableSystem.from_spec(
        SystemSpec(perturbation=Perturbation(force=1.0, torque=0.15), tension_min=0.2,
                   tension_max=40.0, max_thrust=30.0)
    )  # fmt: skip
    assert not statics_validity(CableSystem.from_spec(SystemSpec(platform_mass=1.0)))(
        CURVED_PATH
    ).all()
    more = timing_tolerance(roomy, curved_track, curved_flight, statics_validity(roomy), OPTIONS)
    assert more.start_offset >= tolerance.start_offset
    assert more.speed_mismatch >= tolerance.speed_mismatch
    assert (more.start_offset, more.speed_mismatch) != (tolerance.start_offset,
                                                        tolerance.speed_mismatch)  # fmt: skip
