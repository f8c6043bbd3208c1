"""One overall deadline across an upload's stages (issue 22, item 10): a vehicle that never
answers cannot hold the ground side longer than it was given.

The bounds are the point here, so they are asserted, with margins of a second or more
against the seconds the stages would take on their own.
"""

from __future__ import annotations

import time
from dataclasses import replace

import pytest

from missions.mavlink.errors import MavlinkTimeoutError
from missions.mavlink.params import check_parameters
from missions.mavlink.policy import RetryPolicy
from missions.mavlink.transport import VehicleLink
from missions.mavlink.upload import upload_and_verify
from missions.mock.autopilot import MockConfig
from missions.mock.faults import FaultInjection
from tests.missions.loopback import HOME, waypoint_mission

MARGIN = 1.5  # [s]


def test_parameter_reads_end_by_the_policys_deadline(spawn_mock, fast_policy):
    """ArduPilot never answers for a name it does not know: 11 of them cost 11 x 5 x 0.25 s
    = 13.75 s before; now the read ends by the deadline and reports them unanswered."""
    _, address = spawn_mock(MockConfig(home=HOME))
    policy = replace(fast_policy, deadline_s=1.0)
    expected = {f"NOSUCH_{k}": 1.0 for k in range(11)} | {"WPNAV_ACCEL": 250.0}
    with VehicleLink(address, policy) as link:
        link.wait_heartbeat()
        started = time.monotonic()
        checks = check_parameters(link, expected, policy)
        elapsed = time.monotonic() - started
    assert elapsed < policy.deadline_s + MARGIN, elapsed
    assert [c.name for c in checks] == list(expected)
    assert all(c.found is None for c in checks if c.name.startswith("NOSUCH"))


def test_an_upload_to_a_silent_vehicle_ends_by_the_overall_deadline(spawn_mock):
    """Alone, the upload would wait 5 x 0.5 s for the first request, then 2 x 0.5 s for the
    clearing's ack: 3.5 s. Given 0.5 s in all, it ends then, the clearing included."""
    _, address = spawn_mock(MockConfig(home=HOME, faults=FaultInjection(unresponsive=True)))
    policy = RetryPolicy(request_timeout_s=0.5, retries=4, heartbeat_timeout_s=3.0)
    with VehicleLink(address, policy) as link:
        link.wait_heartbeat()
        started = time.monotonic()
        with pytest.raises(MavlinkTimeoutError, match="deadline"):
            upload_and_verify(link, waypoint_mission(1, 3), policy, ends=started + 0.5)
        elapsed = time.monotonic() - started
    assert elapsed < 0.5 + MARGIN, elapsed


def test_until_cuts_the_deadline_to_what_is_left():
    policy = RetryPolicy(deadline_s=60.0)
    assert policy.until(None) is policy
    assert policy.until(time.monotonic() + 3600).deadline_s == 60.0
    assert 0 < policy.until(time.monotonic() + 10).deadline_s <= 10
    assert 0 < policy.until(time.monotonic() - 5).deadline_s <= 1e-3  # past: at once
