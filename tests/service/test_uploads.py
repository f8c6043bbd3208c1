"""Issue 22, items 9-11: uploads to hostile or unusual vehicles, through the API.

The vehicles are mock ArduCopters (missions/mock) on loopback UDP; the task is recorded done
with hand-made missions (tests/service/fabricated.py), so nothing is planned here.

- item 9: a vehicle answering a parameter with NaN or infinity made the response a 500 (the
  outcome did not encode) although every mission was on board, and NaN went into the
  uploads table;
- item 10: ``UPLOAD_TIMEOUT`` did not bound the parameter reads (99.9 s with 10 s), and sixty
  uploads at once took every thread of the API;
- item 11: three addresses reaching one vehicle passed the "three different vehicles" check.
"""

from __future__ import annotations

import json
import math
import selectors
import socket
import sqlite3
import threading
import time
from collections.abc import Iterator
from concurrent.futures import ThreadPoolExecutor
from contextlib import ExitStack, contextmanager

from missions.mock.autopilot import MockAutopilot, MockConfig
from missions.mock.parameters import ARDUCOPTER_DEFAULTS
from missions.mock.sim_clock import SimClock
from tests.missions.loopback import HOME, free_udp_port, waypoint_mission
from tests.service.conftest import running_service
from tests.service.fabricated import done_task

#: What the plan's .parm assumes: ArduCopter's defaults (a fresh mock holds them).
DEFAULTS = {name: value for name, (value, _) in ARDUCOPTER_DEFAULTS.items()}


@contextmanager
def vehicles(configs: list[MockConfig]) -> Iterator[tuple[list[MockAutopilot], list[str]]]:
    """Started mocks on loopback and the addresses the ground side reaches them at."""
    clock = SimClock(speedup=5.0)
    with ExitStack() as stack:
        mocks, addresses = [], []
        for config in configs:
            port = free_udp_port()
            mock = MockAutopilot(f"udpin:127.0.0.1:{port}", config, clock).start()
            stack.callback(mock.stop)
            mocks.append(mock)
            addresses.append(f"udpout:127.0.0.1:{port}")
        yield mocks, addresses


def fabricated(client, parameters: dict[str, float], drones=(1, 2, 3)) -> str:
    missions = [waypoint_mission(k, 3) for k in drones]
    return done_task(client.app.state.service, missions, [parameters] * 3)


def strict_json(text: str) -> object:
    """JSON as RFC 8259 has it: NaN and Infinity are not JSON."""

    def refuse(constant: str) -> None:
        raise ValueError(f"{constant} is not JSON")

    return json.loads(text, parse_constant=refuse)


# -- item 9 ----------------------------------------------------------------------------------


def test_a_vehicle_answering_nan_or_inf_is_a_409_naming_it_and_the_parameter(tmp_path):
    configs = [
        MockConfig(system_id=1, home=HOME),
        MockConfig(system_id=2, home=HOME, parameters={"WPNAV_ACCEL": math.nan}),
        MockConfig(system_id=3, home=HOME, parameters={"WPNAV_SPEED": math.inf}),
    ]
    with running_service(tmp_path) as client, vehicles(configs) as (mocks, addresses):
        task = fabricated(client, DEFAULTS)
        response = client.post(f"/v1/tasks/{task}/upload", json={"vehicles": addresses})
        assert response.status_code == 409, response.text
        outcome = {v["drone"]: v for v in strict_json(response.text)["vehicles"]}
        assert outcome[1]["ok"] and outcome[1]["parameter_differences"] == []
        for drone, name, shown in ((2, "WPNAV_ACCEL", "nan"), (3, "WPNAV_SPEED", "inf")):
            vehicle = outcome[drone]
            assert not vehicle["ok"] and vehicle["vehicle"] == addresses[drone - 1]
            assert "uploaded and verified" in vehicle["detail"]
            expected = f"{name} should be {DEFAULTS[name]:g}, the vehicle has {shown}"
            assert expected in vehicle["detail"]
            (difference,) = vehicle["parameter_differences"]
            assert difference["name"] == name and difference["found"] is None
            assert difference["found_text"] == shown
        assert all(len(mock.mission) == 5 for mock in mocks)  # every mission on board
        # the outcome stored is JSON too
        database = sqlite3.connect(tmp_path / "flycrane.db")
        try:
            (stored,) = database.execute("SELECT outcome FROM uploads").fetchone()
        finally:
            database.close()
        assert strict_json(stored)["vehicles"][1]["parameter_differences"][0]["found"] is None


# -- item 11 ---------------------------------------------------------------------------------


class Hub:
    """One vehicle behind three addresses (as on a shared radio network): what a ground
    station sends to 127.0.0.{1,2,3}:port reaches the vehicle, what the vehicle sends reaches
    every ground station that spoke. All on loopback; stopped (joined) on exit."""

    def __init__(self, vehicle_port: int) -> None:
        self.port = free_udp_port()
        self.vehicle = ("127.0.0.1", vehicle_port)
        self.fronts = []
        for host in ("127.0.0.1", "127.0.0.2", "127.0.0.3"):
            front = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
            front.bind((host, self.port))
            self.fronts.append(front)
        self.back = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.back.bind(("127.0.0.1", 0))
        self.clients: dict[socket.socket, tuple[str, int]] = {}
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="test-hub", daemon=True)

    @property
    def addresses(self) -> list[str]:
        return [f"udpout:{front.getsockname()[0]}:{self.port}" for front in self.fronts]

    def _run(self) -> None:
        with selectors.DefaultSelector() as selector:
            for sock in (*self.fronts, self.back):
                selector.register(sock, selectors.EVENT_READ)
            while not self._stop.is_set():
                for key, _ in selector.select(timeout=0.05):
                    sock = key.fileobj
                    assert isinstance(sock, socket.socket)
                    data, sender = sock.recvfrom(65536)
                    if sock is self.back:
                        for front, client in list(self.clients.items()):
                            front.sendto(data, client)
                    else:
                        self.clients[sock] = sender
                        self.back.sendto(data, self.vehicle)

    def __enter__(self) -> Hub:
        self._thread.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self._stop.set()
        self._thread.join(timeout=5.0)
        for sock in (*self.fronts, self.back):
            sock.close()


def test_three_addresses_of_one_vehicle_are_refused_before_any_upload(tmp_path):
    one = [MockConfig(system_id=7, home=HOME)]
    with running_service(tmp_path) as client, vehicles(one) as ((mock,), (address,)):
        with Hub(int(address.rsplit(":", 1)[1])) as hub:
            task = fabricated(client, DEFAULTS)
            addresses = hub.addresses
            response = client.post(f"/v1/tasks/{task}/upload", json={"vehicles": addresses})
        assert response.status_code == 422, response.text
        detail = response.json()["detail"]
        assert [d["loc"] for d in detail] == [["body", "vehicles[1]"], ["body", "vehicles[2]"]]
        for k, problem in ((1, detail[0]), (2, detail[1])):
            assert addresses[k] in problem["msg"] and addresses[0] in problem["msg"]
            assert "system id 7" in problem["msg"]
        assert len(mock.mission) <= 1  # nothing uploaded: the mock holds its home only


# -- item 10 ---------------------------------------------------------------------------------

#: Parameters no ArduCopter knows: it never answers for them (it stays silent).
UNKNOWN = {f"NOSUCH_{k}": 1.0 for k in range(11)}
#: The setting under test, and how far past it an answer may come (closing the links).
UPLOAD_TIMEOUT, MARGIN = 8.0, 5.0


def test_upload_timeout_bounds_the_whole_upload_parameter_reads_included(tmp_path):
    """Before: 11 silent parameters x 6 requests x 1.5 s = 99 s, whatever the setting."""
    configs = [MockConfig(system_id=k, home=HOME) for k in (1, 2, 3)]
    with (
        running_service(tmp_path, upload_timeout=UPLOAD_TIMEOUT) as client,
        vehicles(configs) as (mocks, addresses),
    ):
        task = fabricated(client, UNKNOWN)
        started = time.monotonic()
        response = client.post(f"/v1/tasks/{task}/upload", json={"vehicles": addresses})
        elapsed = time.monotonic() - started
        assert elapsed < UPLOAD_TIMEOUT + MARGIN, elapsed
        assert response.status_code == 409, response.text
        for vehicle in response.json()["vehicles"]:
            assert "uploaded and verified" in vehicle["detail"]
            assert {d["name"] for d in vehicle["parameter_differences"]} == set(UNKNOWN)
            assert all(d["found"] is None for d in vehicle["parameter_differences"])
        assert all(len(mock.mission) == 5 for mock in mocks)


def test_uploads_beyond_the_limit_are_refused_and_the_api_keeps_answering(tmp_path):
    """Two uploads at most (the setting): the others are told to retry later at once, and
    /healthz answers while the two wait for vehicles that never answer."""
    with running_service(tmp_path, upload_timeout=10.0, max_concurrent_uploads=2) as client:
        task = fabricated(client, DEFAULTS)
        silent = [f"udpout:127.0.0.1:{free_udp_port()}" for _ in range(3)]

        def upload(_: int):
            return client.post(f"/v1/tasks/{task}/upload", json={"vehicles": silent})

        with ThreadPoolExecutor(6) as senders:
            futures = [senders.submit(upload, k) for k in range(6)]
            deadline = time.monotonic() + 60.0
            while sum(f.done() for f in futures) < 4:  # the refusals come at once
                assert time.monotonic() < deadline, "no refusals"
                time.sleep(0.01)
            health = client.get("/healthz")
            running = sum(not f.done() for f in futures)  # still waiting for heartbeats
            answers = [f.result() for f in futures]
        assert health.status_code == 200 and running == 2, (health.text, running)
        codes = sorted(a.status_code for a in answers)
        assert codes == [502, 502, 503, 503, 503, 503], [a.text for a in answers]
        for answer in answers:
            if answer.status_code == 503:
                assert answer.headers["retry-after"] == "10"
                assert "2 uploads are running" in answer.json()["detail"]
