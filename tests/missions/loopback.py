"""Loopback fixtures of the MAVLink and mock tests (their conftests import them): free
UDP ports, mocks that are always stopped, a fast retry policy, and a check that no test
leaves a thread running."""

from __future__ import annotations

import socket
import threading
import time
from collections.abc import Callable, Iterator

import pytest

from missions.export.items import DroneMission, MavCmd, MavFrame, MissionItem
from missions.mavlink.policy import RetryPolicy
from missions.mock.autopilot import MockAutopilot, MockConfig
from missions.mock.config import Geodetic
from missions.mock.sim_clock import SimClock

HOME = Geodetic(47.397742, 8.545594, 488.0)


def free_udp_port() -> int:
    """A UDP port nothing listens on right now (the OS picks it)."""
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@pytest.fixture(autouse=True)
def no_leaked_threads() -> Iterator[None]:
    before = set(threading.enumerate())
    yield
    deadline = time.monotonic() + 3.0
    while time.monotonic() < deadline:
        # "Dummy-N" threads are foreign (C++) threads that once ran a Python callback,
        # e.g. MAVSDK's: Python lists them forever, they are not ours to join.
        leaked = [
            t
            for t in threading.enumerate()
            if t not in before and t.is_alive() and not t.name.startswith("Dummy-")
        ]
        if not leaked:
            return
        time.sleep(0.02)
    pytest.fail(f"threads left running: {[t.name for t in leaked]}")


@pytest.fixture
def fast_policy() -> RetryPolicy:
    """Loopback answers in milliseconds, so short timeouts keep failing tests quick."""
    return RetryPolicy(
        request_timeout_s=0.25,
        retries=4,
        deadline_s=20.0,
        no_space_backoff_s=0.1,
        no_space_retry_s=5.0,
        heartbeat_timeout_s=3.0,
        gcs_heartbeat_interval_s=0.1,
    )


MockFactory = Callable[..., tuple[MockAutopilot, str]]


@pytest.fixture
def spawn_mock() -> Iterator[MockFactory]:
    """``spawn_mock(config, clock) -> (mock, address for the ground side)``; all stopped."""
    started: list[MockAutopilot] = []

    def spawn(
        config: MockConfig | None = None, clock: SimClock | None = None
    ) -> tuple[MockAutopilot, str]:
        port = free_udp_port()
        mock = MockAutopilot(
            f"udpin:127.0.0.1:{port}",
            config or MockConfig(home=HOME),
            clock or SimClock(speedup=5.0),
        ).start()
        started.append(mock)
        return mock, f"udpout:127.0.0.1:{port}"

    yield spawn
    for mock in started:
        mock.stop()


def waypoint_mission(drone: int, count: int) -> DroneMission:
    """Home, takeoff to 5 m, then ``count`` waypoints 1e-5 degree apart with distinct params,
    so that any swapped or altered item shows."""
    items = [
        MissionItem(
            0,
            MavFrame.GLOBAL_RELATIVE_ALT_INT,
            MavCmd.NAV_WAYPOINT,
            x=round(HOME.lat_deg * 1e7),
            y=round(HOME.lon_deg * 1e7),
        ),
        MissionItem(1, MavFrame.GLOBAL_RELATIVE_ALT_INT, MavCmd.NAV_TAKEOFF, z=5.0),
    ]
    for k in range(count):
        items.append(
            MissionItem(
                len(items),
                MavFrame.GLOBAL_RELATIVE_ALT_INT,
                MavCmd.NAV_WAYPOINT,
                param1=0.1 * k,
                param2=0.5 + drone,
                param4=float("nan"),
                x=round(HOME.lat_deg * 1e7) + 100 * k + drone,
                y=round(HOME.lon_deg * 1e7) - 37 * k,
                z=5.0 + 0.123 * k,
            )
        )
    return DroneMission(drone, tuple(items))
