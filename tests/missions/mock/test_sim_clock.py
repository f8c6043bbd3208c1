"""The lock-step clock: no mock starves its I/O, mocks on one clock stay on one time.

The loaded machine is imitated deterministically: a mock whose every simulation step costs
more wall time than the step is worth at its speed-up (a sleep in the step), which is what
a busy core did to the old catch-up loop (it stepped towards the present without reading
its socket and stopped answering: "arm failed ... no answer within 1.25 s").
"""

from __future__ import annotations

import threading
import time

import pytest

from missions.mavlink.commands import arm
from missions.mavlink.policy import RetryPolicy
from missions.mavlink.transport import VehicleLink
from missions.mock.autopilot import MockAutopilot
from missions.mock.sim_clock import PEER_POLL_S, SimClock
from tests.missions.loopback import MockFactory


def slow_steps(monkeypatch: pytest.MonkeyPatch, mock: MockAutopilot, wall_s: float) -> None:
    """Make every simulation step of ``mock`` cost ``wall_s`` of wall time."""
    step = mock._advance

    def slow(dt_s: float) -> None:
        time.sleep(wall_s)
        step(dt_s)

    monkeypatch.setattr(mock, "_advance", slow)


def test_a_mock_whose_steps_overrun_still_answers_at_once(
    spawn_mock: MockFactory, monkeypatch: pytest.MonkeyPatch
):
    """Steps of 20 ms at x20 are worth 1 ms of wall time; each costs 5 ms here, so the
    simulation can never keep pace. Commands are still answered within one request
    timeout, every time: no retries are needed."""
    clock = SimClock(speedup=20.0)
    mock, address = spawn_mock(clock=clock)
    slow_steps(monkeypatch, mock, 0.005)
    time.sleep(0.3)  # let it fall behind
    strict = RetryPolicy(request_timeout_s=0.25, retries=0, deadline_s=5.0)
    with VehicleLink(address, strict, name="loaded") as link:
        link.wait_heartbeat()
        for _ in range(5):
            arm(link, strict)


def test_mocks_on_one_clock_stay_in_lock_step(
    spawn_mock: MockFactory, monkeypatch: pytest.MonkeyPatch
):
    """One of two mocks is slow: the other waits for it, so both are at the same step
    (within one) whenever one is looked at."""
    clock = SimClock(speedup=20.0)
    fast, _ = spawn_mock(clock=clock)
    slow, _ = spawn_mock(clock=clock)
    slow_steps(monkeypatch, slow, 0.004)
    gaps = []
    for _ in range(50):
        time.sleep(0.005)
        gaps.append(abs(fast._steps - slow._steps))
    assert max(gaps) <= 1
    assert slow._steps > 10


def test_simulated_time_never_runs_ahead_of_the_speedup():
    """A vehicle stepping as fast as it may is never ahead of ``speedup`` x wall time, and
    when it must wait, the wait is at most one step's worth of wall time."""
    clock = SimClock(speedup=10.0, step_s=0.02)
    started = time.monotonic()
    vehicle, first = clock.join()
    step = first
    while time.monotonic() - started < 0.2:
        wait = clock.may_begin(vehicle, step + 1)
        if wait == 0.0:
            step += 1
            clock.finished(vehicle, step)
            assert (step - first) * 0.02 <= (time.monotonic() - started) * 10.0 + 0.02
        else:
            assert wait <= 0.02 / 10.0 + 1e-9
            time.sleep(wait)
    assert step > first


def test_peers_wait_for_the_last_and_leaving_releases_them():
    clock = SimClock(speedup=1000.0)
    first, done = clock.join()
    second, _ = clock.join()
    time.sleep(0.01)
    assert clock.may_begin(first, done + 1) == 0.0
    clock.finished(first, done + 1)
    assert clock.may_begin(first, done + 2) == PEER_POLL_S  # second has not finished done + 1
    clock.leave(second)
    # no peer to wait for: at most the pacing of one step remains (how much of it depends on
    # how long the calls above took, so only its bound is asserted)
    assert clock.may_begin(first, done + 2) <= clock.step_s / clock.speedup


def test_a_held_clock_stands_still_and_runs_on_without_a_jump():
    clock = SimClock(speedup=1000.0, step_s=0.02)
    vehicle, done = clock.join()
    time.sleep(0.01)  # 10 s simulated: well past the lag limit
    with clock.held() as at:
        assert at == clock.now()
        step = done
        while clock.may_begin(vehicle, step + 1) == 0.0:
            step += 1
            clock.finished(vehicle, step)
        time.sleep(0.02)  # 20 s simulated, if the clock were running
        assert clock.may_begin(vehicle, step + 1) > 0.0
    # after the hold at most the lag limit (debt forgotten) plus the time since, no 20 s jump
    released = time.monotonic()
    allowed = step
    while clock.may_begin(vehicle, allowed + 1) == 0.0:
        allowed += 1
        clock.finished(vehicle, allowed)
    since = (time.monotonic() - released) * clock.speedup / clock.step_s  # steps of wall time
    assert allowed - step <= clock.max_lag_steps + since + 2  # a jump would be 1,000 steps


def test_a_clock_held_at_a_time_runs_to_it_exactly_and_stands_there():
    """Two vehicles stepping in threads: held 1 s ahead, both have finished exactly that
    step and begin no further one inside the block; the clock runs on after it."""
    clock = SimClock(speedup=50.0, step_s=0.02)
    stop = threading.Event()
    done: dict[int, int] = {}

    def vehicle() -> None:
        me, step = clock.join()
        done[me] = step
        while not stop.is_set():
            if clock.may_begin(me, step + 1) == 0.0:
                step += 1
                clock.finished(me, step)
                done[me] = step
            else:
                time.sleep(0.0002)
        clock.leave(me)

    threads = [threading.Thread(target=vehicle) for _ in range(2)]
    for thread in threads:
        thread.start()
    try:
        while len(done) < 2:
            time.sleep(0.001)
        target = round(clock.now() / 0.02) + 50
        with clock.held(at=target * 0.02) as at:
            assert at == pytest.approx(target * 0.02)
            time.sleep(0.1)  # 5 s simulated, if the clock were running
            assert set(done.values()) == {target}
        deadline = time.monotonic() + 10.0  # runs on: at once, or as soon as the load allows
        while min(done.values()) <= target and time.monotonic() < deadline:
            time.sleep(0.001)
        assert min(done.values()) > target
        with pytest.raises(ValueError, match="past"):
            with clock.held(at=target * 0.02):
                pass
    finally:
        stop.set()
        for thread in threads:
            thread.join()


def test_a_lagging_simulation_never_sprints():
    """After a stall the pacing forgets the debt beyond ``max_lag_steps``."""
    clock = SimClock(speedup=100.0, step_s=0.02, max_lag_steps=5)
    vehicle, done = clock.join()
    time.sleep(0.1)  # 500 steps' worth of wall time
    allowed = done
    while clock.may_begin(vehicle, allowed + 1) == 0.0 and allowed - done < 100:
        allowed += 1
        clock.finished(vehicle, allowed)
    assert allowed - done <= 5 + 2


@pytest.mark.parametrize("bad", [{"speedup": 0.0}, {"step_s": -1.0}, {"max_lag_steps": 0}])
def test_bad_settings_are_refused_by_name(bad):
    with pytest.raises(ValueError, match=next(iter(bad))):
        SimClock(**bad)


def test_threads_end_with_the_mock(spawn_mock: MockFactory):
    mock, _ = spawn_mock()
    mock.stop()
    assert not any(t.name.startswith("mock-autopilot") for t in threading.enumerate())
