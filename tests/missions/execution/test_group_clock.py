"""The group clock against closed-form plan time, and the rate rule's mapping."""

from __future__ import annotations

import numpy as np
import pytest

from missions.execution.group_clock import GroupClock, RatePolicy


def test_plan_time_runs_with_common_time_from_the_start_and_holds_at_the_ends():
    clock = GroupClock(start=100.0, duration=10.0)
    assert clock.state(99.0) == (0.0, 0.0, 0.0)  # waits at the start
    assert clock.tau(103.25) == pytest.approx(3.25)
    assert clock.state(103.25)[1] == 1.0
    assert clock.state(130.0) == (10.0, 0.0, 0.0)  # holds at the end


def test_a_stop_ramps_the_rate_down_and_covers_half_the_ramp_in_plan_time():
    """Rate 1 -> 0 at slope 2/s: a 0.5 s ramp over which plan time advances 0.25 s
    (the area under the rate), then stays."""
    clock = GroupClock(start=0.0, duration=60.0)
    clock.steer(10.0, 0.0, 2.0)
    tau, rate, slope = clock.state(10.25)
    assert rate == pytest.approx(0.5) and slope == pytest.approx(-2.0)
    assert tau == pytest.approx(10.0 + 0.25 - 0.5 * 2.0 * 0.25**2)
    assert clock.tau(10.5) == pytest.approx(10.25)
    assert clock.tau(20.0) == pytest.approx(10.25)
    assert clock.state(20.0)[1] == 0.0


def test_plan_time_is_continuous_and_never_runs_backwards_through_changes():
    clock = GroupClock(start=0.0, duration=100.0)
    for t, target in ((5.0, 0.3), (6.0, 1.0), (8.0, 0.0), (9.0, 0.7)):
        clock.steer(t, target, 0.8)
    t = np.linspace(0.0, 20.0, 20001)
    tau = np.array([clock.tau(x) for x in t])
    assert np.all(np.diff(tau) >= -1e-12)
    rate = np.array([clock.state(x)[1] for x in t])
    # tau is the integral of the rate (midpoint rule on a fine grid)
    middle = np.array([clock.state(x)[1] for x in (t[1:] + t[:-1]) / 2])
    integral = np.concatenate([[0.0], np.cumsum(middle * np.diff(t))])
    np.testing.assert_allclose(tau, integral, atol=1e-6)
    # the plan starts at full rate (its trajectory starts at rest); changes are ramps
    assert np.max(np.abs(np.diff(rate[1:]))) <= 0.8 * (t[1] - t[0]) + 1e-12


def test_the_past_is_never_rewritten():
    clock = GroupClock(start=0.0, duration=10.0)
    clock.steer(5.0, 0.5, 1.0)
    with pytest.raises(ValueError, match="before the last change"):
        clock.steer(4.0, 1.0, 1.0)


def test_the_rate_rule_runs_full_below_its_threshold_and_stops_at_a_tolerance():
    policy = RatePolicy(tracking_tolerance=0.1, formation_tolerance=0.2, slow_from=0.4)
    assert policy.target_rate(policy.badness(np.array([0.03, 0.0, 0.04]), np.zeros(3))) == 1.0
    assert policy.target_rate(policy.badness(np.array([0.07, 0.0, 0.0]), np.zeros(3))) == (
        pytest.approx(0.5)
    )
    assert policy.target_rate(policy.badness(np.zeros(3), np.array([0.0, 0.2, 0.0]))) == 0.0
    clock = GroupClock(start=0.0, duration=10.0)
    policy.steer(clock, 1.0, badness=0.0, stop=True)  # a fault: stop whatever the errors
    assert clock.target == 0.0 and clock.state(1.0 + 1.0 / policy.braking)[1] == 0.0


def test_the_rate_rule_ignores_changes_within_its_deadband_but_not_a_return_to_full_rate():
    policy = RatePolicy(tracking_tolerance=0.1, formation_tolerance=0.1, slow_from=0.5)
    clock = GroupClock(start=0.0, duration=30.0)
    policy.steer(clock, 1.0, badness=0.52)  # target 0.96: within the deadband of 1
    assert len(clock.segments) == 1
    policy.steer(clock, 2.0, badness=0.7)  # target 0.6
    assert clock.target == pytest.approx(0.6) and len(clock.segments) == 2
    policy.steer(clock, 3.0, badness=0.68)  # 0.64: noise
    assert len(clock.segments) == 2
    policy.steer(clock, 4.0, badness=0.52)  # 0.96 -> back to full rate, exactly 1
    assert clock.target == 1.0


def test_rejoining_a_segment_follows_its_law_from_then_on():
    """A player that heard only the first segment (slowing 1 -> 0.5 over 1 s) plays it;
    the clock, changed since, rejoins it mid-ramp and agrees with it ever after."""
    clock = GroupClock(start=0.0, duration=60.0)
    clock.steer(10.0, 0.5, 0.5)
    heard = clock.segments[-1]
    clock.steer(10.4, 0.0, 2.0)
    clock.rejoin(10.6, heard)
    for t in (10.6, 10.8, 11.0, 15.0):
        assert clock.state(t) == pytest.approx(heard.state(t))
    # closed form: at 15 s, 10 + 1 s of ramp averaging 0.75, then 4 s at 0.5
    assert clock.tau(15.0) == pytest.approx(10.0 + 0.75 + 2.0)
