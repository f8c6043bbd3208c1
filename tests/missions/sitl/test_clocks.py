"""Bringing the simulators' clocks together, against simulated vehicles whose clocks lead by
known amounts and follow SIM_SPEEDUP as SITL's do."""

from __future__ import annotations

import threading
import time
from collections.abc import Callable, Mapping
from types import SimpleNamespace
from typing import Any

import pytest

from missions.mavlink.policy import RetryPolicy
from missions.sitl import clocks
from missions.sitl.clocks import LEAD_TOLERANCE_S, align_clocks, clock_leads

SPEEDUP = 2.0


class Clocked:
    """A vehicle link's stand-in: GLOBAL_POSITION_INT at 100 Hz of wall time, its boot time
    ``lead`` [s] ahead of a common origin and advancing at ``pace`` per wall second."""

    def __init__(self, name: str, lead: float) -> None:
        self.name = name
        self.pace = SPEEDUP
        self._boot = lead
        self._at = time.monotonic()
        self._listeners: list[Callable[[Any], None]] = []
        self._lock = threading.Lock()

    def boot(self) -> float:
        with self._lock:
            now = time.monotonic()
            self._boot += self.pace * (now - self._at)
            self._at = now
            return self._boot

    def set_pace(self, pace: float) -> None:
        self.boot()
        with self._lock:
            self.pace = pace

    def add_listener(self, types: Any, callback: Callable[[Any], None]) -> None:
        self._listeners.append(callback)

    def remove_listener(self, callback: Callable[[Any], None]) -> None:
        self._listeners.remove(callback)

    def send(self) -> None:
        msg = SimpleNamespace(time_boot_ms=int(1000 * self.boot()))
        for callback in list(self._listeners):
            callback(msg)


@pytest.fixture
def fleet(monkeypatch: pytest.MonkeyPatch):
    links = [Clocked("drone1", 0.0), Clocked("drone2", 0.030), Clocked("drone3", 0.085)]
    done = threading.Event()

    def feed() -> None:
        while not done.wait(0.01):
            for link in links:
                link.send()

    def set_parameters(link: Clocked, values: Mapping[str, float], policy: RetryPolicy):
        link.set_pace(values["SIM_SPEEDUP"])

    monkeypatch.setattr(clocks, "set_parameters", set_parameters)
    feeder = threading.Thread(target=feed, daemon=True)
    feeder.start()
    yield links
    done.set()
    feeder.join()


def test_each_lead_is_measured_against_the_latest_clock(fleet):
    leads = clock_leads(fleet, SPEEDUP)  # type: ignore[arg-type]
    # the boot times are whole milliseconds, as SITL sends them
    assert leads == pytest.approx({"drone1": 0.0, "drone2": 0.030, "drone3": 0.085}, abs=0.002)


def test_the_leading_clocks_are_held_back_until_the_three_agree(fleet):
    aligned = align_clocks(fleet, SPEEDUP, RetryPolicy())  # type: ignore[arg-type]
    assert aligned.before["drone3"] == pytest.approx(0.085, abs=0.002)
    assert max(aligned.after.values()) <= LEAD_TOLERANCE_S
    assert [link.pace for link in fleet] == [SPEEDUP] * 3
    # the simulated clocks themselves, not only their measure (whole milliseconds sent)
    boots = [link.boot() for link in fleet]
    assert max(boots) - min(boots) <= LEAD_TOLERANCE_S + 0.002


def test_a_clock_that_keeps_its_lead_is_reported(fleet, monkeypatch, caplog):
    """A simulator starved of the host's cores runs below any pace it is given: its lead
    stays, and the operator is told."""
    monkeypatch.setattr(clocks, "set_parameters", lambda link, values, policy: None)
    with caplog.at_level("WARNING", logger="missions.sitl.clocks"):
        aligned = align_clocks(fleet, SPEEDUP, RetryPolicy())  # type: ignore[arg-type]
    assert aligned.after["drone3"] == pytest.approx(0.085, abs=0.002)
    assert "clock leads before the release" in caplog.text
