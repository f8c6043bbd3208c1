"""The mock's spline legs against ArduCopter 4.5.7 SITL: the missions of two recorded SITL
flights (Rescue and Puzzle, ``tests/missions/data/README.md``) flown by three mocks the way
the SITL harness flew them, every leg within 10 % of its SITL duration (issue 11, item 5).

The mocks step in lock step on one clock, so the outcome does not depend on the machine's
speed; wall time only bounds how long the test may take. A mock reports a leg's start at
the end of the simulation step it fell in, and the log reader times that report by the
midpoint of the position samples around it (one per step), so each leg is measured within
one step, :data:`STEP_S`: 2.4 % of the shortest (0.21 s) legs.
"""

from __future__ import annotations

import json
import threading
import time
from pathlib import Path

import numpy as np
import pytest

from missions.export.items import DroneMission, MissionItem
from missions.flight_report.leg_times import MISSION_FIELDS, leg_durations, spline_waypoints
from missions.flight_report.vehicle_log import read_vehicle_log
from missions.mavlink.commands import release, set_message_interval
from missions.mavlink.fleet import Fleet, on_every_vehicle
from missions.mavlink.params import set_parameters
from missions.mavlink.policy import RetryPolicy
from missions.mavlink.tlog import TlogWriter
from missions.mock.autopilot import MockConfig
from missions.mock.config import Geodetic
from missions.mock.sim_clock import SimClock
from missions.options import GeodeticOrigin

DATA = Path(__file__).parents[1] / "data" / "sitl_leg_times.json"
#: The simulation step, and the position stream (one sample per step) [s].
STEP_S = 0.005
#: The issue's bound on every leg, relative to SITL's duration.
TOLERANCE = 0.10
#: Generous wall-time bounds [s]: a loaded machine slows the lock-step clock, never the
#: outcome.
FLIGHT_WALL_S = 600.0
POLICY = RetryPolicy(request_timeout_s=1.0, retries=4, deadline_s=60.0, no_space_backoff_s=0.1,
                     no_space_retry_s=5.0, heartbeat_timeout_s=10.0,
                     gcs_heartbeat_interval_s=0.5)  # fmt: skip


def load_flights() -> list[dict]:
    return json.loads(DATA.read_text(encoding="utf-8"))["flights"]


def mission_of(drone: int, rows: list[list[float]]) -> DroneMission:
    items = []
    for seq, row in enumerate(rows):
        fields = dict(zip(MISSION_FIELDS, row, strict=True))
        fields.update(frame=int(fields["frame"]), command=int(fields["command"]),
                      x=int(fields["x"]), y=int(fields["y"]))  # fmt: skip
        items.append(MissionItem(seq=seq, **fields))
    return DroneMission(drone, tuple(items))


class Progress:
    """The current item of every vehicle, the items each has reached, and how many position
    samples it has sent."""

    def __init__(self, fleet: Fleet) -> None:
        self.current = {link.name: -1 for link in fleet.links}
        self.reached: dict[str, set[int]] = {link.name: set() for link in fleet.links}
        self.samples = dict.fromkeys(self.current, 0)
        self._changed = threading.Condition()
        kinds = ("MISSION_CURRENT", "MISSION_ITEM_REACHED", "GLOBAL_POSITION_INT")
        for link in fleet.links:
            link.add_listener(kinds, self._on(link.name))

    def _on(self, name: str):
        def listener(msg) -> None:
            with self._changed:
                kind = msg.get_type()
                if kind == "MISSION_CURRENT":
                    self.current[name] = msg.seq
                elif kind == "MISSION_ITEM_REACHED":
                    self.reached[name].add(msg.seq)
                else:
                    self.samples[name] += 1
                self._changed.notify_all()

        return listener

    def wait(self, condition, timeout_s: float, what: str) -> None:
        with self._changed:
            if not self._changed.wait_for(condition, timeout_s):
                pytest.fail(f"{what} not within {timeout_s:.0f} s of wall time: {self.current}")


def fly_on_mocks(flight: dict, spawn_mock, directory: Path) -> dict[str, np.ndarray]:
    """Fly the flight's missions on three mocks as ``missions.sitl.harness`` flies SITL: set
    the parameters, upload, arm, start, release from the hold with MISSION_SET_CURRENT; the
    legs of every drone, read from its tlog."""
    clock = SimClock(speedup=20.0, step_s=STEP_S)
    missions = [mission_of(k + 1, d["mission"]) for k, d in enumerate(flight["drones"])]
    addresses = []
    for k, mission in enumerate(missions):
        home = mission.items[0]
        config = MockConfig(system_id=k + 1, home=Geodetic(home.x * 1e-7, home.y * 1e-7, home.z))
        addresses.append(spawn_mock(config, clock)[1])
    names = [d["name"] for d in flight["drones"]]
    with Fleet.connect(addresses, POLICY, names) as fleet:
        writers = [TlogWriter(link, directory / f"{n}.tlog").start()
                   for link, n in zip(fleet.links, names, strict=True)]  # fmt: skip
        try:
            progress = Progress(fleet)
            parameters = {d["name"]: d["parameters"] for d in flight["drones"]}
            on_every_vehicle(
                fleet.links, "parameters", lambda v: set_parameters(v, parameters[v.name], POLICY)
            )
            on_every_vehicle(
                fleet.links,
                "stream",
                lambda v: set_message_interval(v, "GLOBAL_POSITION_INT", STEP_S, POLICY),
            )
            fleet.upload(missions)
            fleet.arm()
            fleet.start()
            hold = flight["release_seq"] - 1
            progress.wait(lambda: set(progress.current.values()) == {hold}, 60.0, "the hold")
            release(fleet.links, flight["release_seq"], POLICY)
            last = {n: spline_waypoints(m.items)[-1] for n, m in zip(names, missions, strict=True)}
            progress.wait(
                lambda: all(last[n] in progress.reached[n] for n in names),
                FLIGHT_WALL_S,
                "the last waypoints",
            )
            # the log times an event by the position samples around it: record a few more
            after = {n: progress.samples[n] + 10 for n in names}
            progress.wait(lambda: all(progress.samples[n] >= after[n] for n in names), 60.0,
                          "the samples after the end")  # fmt: skip
        finally:
            for writer in writers:
                writer.stop()
    legs = {}
    for name, mission in zip(names, missions, strict=True):
        log = read_vehicle_log(directory / f"{name}.tlog", name, GeodeticOrigin())
        legs[name] = leg_durations(log.current, log.reached, mission.items,
                                   flight["release_seq"], name)  # fmt: skip
    return legs


@pytest.mark.parametrize("index", [0, 1], ids=["rescue", "puzzle"])
def test_mock_legs_last_as_long_as_sitl_legs(index, spawn_mock, tmp_path):
    flight = load_flights()[index]
    started = time.monotonic()
    legs = fly_on_mocks(flight, spawn_mock, tmp_path)
    for drone in flight["drones"]:
        sitl = np.array(drone["legs_s"])
        mock = legs[drone["name"]]
        assert mock.shape == sitl.shape, drone["name"]
        error = (mock - sitl) / sitl
        worst = int(np.argmax(np.abs(error)))
        assert abs(error[worst]) <= TOLERANCE, (
            f"{flight['flight']} {drone['name']} leg {worst + 1}: mock {mock[worst]:.3f} s, "
            f"SITL {sitl[worst]:.3f} s ({error[worst]:+.1%})"
        )
    assert time.monotonic() - started < FLIGHT_WALL_S
