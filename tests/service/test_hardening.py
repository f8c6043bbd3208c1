"""Issue 10's defects, one test each (items 1-10; faults and fuzzing have files of their own).

Every request here is answered by the real application with real worker processes; the
tasks that reach a worker are cancelled or fail fast, none is planned to the end.
"""

from __future__ import annotations

import math
import os
import sqlite3
import threading
from concurrent.futures import ThreadPoolExecutor
from datetime import UTC, datetime, timedelta

import pytest
from fastapi.testclient import TestClient

from flycrane.world.scene import SCENES_DIR, load_scene
from service.app import create_app
from service.settings import Settings
from tests.service.conftest import TEST_HOST, running_service

RESCUE = load_scene("rescue")[0].model_dump(mode="json")
RESCUE_START = RESCUE["start"]


@pytest.fixture(scope="module")
def client(tmp_path_factory):
    with running_service(tmp_path_factory.mktemp("hardening"), max_request_bytes=20_000) as c:
        yield c


def assert_refused(response, location: list, words: str = "") -> None:
    assert response.status_code == 422, response.text
    details = response.json()["detail"]
    assert any(d["loc"][: len(location)] == location and words in d["msg"] for d in details), (
        details
    )


# -- item 1: a task's scene string is never a path on the server -----------------------------


@pytest.fixture
def scene_file(tmp_path):
    path = tmp_path / "copy_of_rescue.toml"
    path.write_bytes((SCENES_DIR / "rescue.toml").read_bytes())
    return path


@pytest.mark.parametrize("where", ["file", "missing", "device", "fifo"])
def test_a_scene_path_is_refused_like_any_unknown_name(client, scene_file, tmp_path, where):
    """A valid scene file, a missing one, /dev/urandom (grew the server to 7 GB) and a FIFO
    (blocked a thread for ever) all get the same answer, which says nothing about the disk."""
    fifo = tmp_path / "pipe"
    os.mkfifo(fifo)
    name = {
        "file": str(scene_file),
        "missing": str(tmp_path / "nothing_here.toml"),
        "device": "/dev/urandom",
        "fifo": str(fifo),
    }[where]
    before = client.get("/v1/tasks").json()["total"]
    response = client.post("/v1/tasks", json={"scene": name})
    presets = ", ".join(sorted(path.stem for path in SCENES_DIR.glob("*.toml")))
    assert_refused(response, ["body", "scene"], f"among the presets; known: {presets}")
    assert response.json()["detail"][0]["msg"] == (
        f"no scene {name!r} among the presets; known: {presets}"
    )
    assert client.get("/v1/tasks").json()["total"] == before


def test_a_mesh_file_in_an_inline_scene_is_refused_naming_the_obstacle(client, scene_file):
    mesh = {"kind": "mesh", "file": str(scene_file)}
    response = client.post("/v1/tasks", json={"scene": {**RESCUE, "obstacles": [mesh]}})
    assert_refused(response, ["body", "scene", "obstacles[0]", "file"], "vertices and faces")


# -- item 2: geometry the collision checker cannot use ----------------------------------------


def test_a_mesh_with_a_huge_vertex_through_the_start_is_refused(client):
    # A sheet through the footbridge at its start (z = 0.45 - 0.35 = 0.1 m).
    sheet = {
        "kind": "mesh",
        "vertices": [[-3, -3, 0.1], [3, -3, 0.1], [0, 1e300, 0.1]],
        "faces": [[0, 1, 2]],
    }
    response = client.post("/v1/tasks", json={"scene": {**RESCUE, "obstacles": [sheet]}})
    assert_refused(response, ["body", "scene", "obstacles", 0, "vertices", 2, 1])


# -- items 3, 8 and 9: every input bounded, every refusal a 422 naming its field ---------------


INF = math.inf


@pytest.mark.parametrize(
    ("body", "location"),
    [
        # item 3: work a single request could cause
        ({"mission": {"check_resolution": 1e-6}}, ["mission", "check_resolution"]),
        ({"mission": {"max_drone_speed": 1e-9}}, ["mission", "max_drone_speed"]),
        # item 8: these were 500s
        (
            {"scene": {**RESCUE, "payload": {**RESCUE["payload"], "com_offset": [INF, 0, 0]}}},
            ["scene", "payload", "com_offset", 0],
        ),
        (
            {"scene": {**RESCUE, "collision": {"drone_radius": 1e308}}},
            ["scene", "collision", "drone_radius"],
        ),
        # item 9: accepted, then failed after planning (or never)
        ({"planner": {"step": INF}}, ["planner", "step"]),
        ({"planner": {"init_temperature": INF}}, ["planner", "init_temperature"]),
        ({"planner": {"cost_threshold": INF}}, ["planner", "cost_threshold"]),
        ({"mission": {"acceptance_radius": INF}}, ["mission", "acceptance_radius"]),
        ({"mission": {"max_platform_deviation": INF}}, ["mission", "max_platform_deviation"]),
        ({"mission": {"start_time_utc": "0001-01-01T00:00:00Z"}}, ["mission", "start_time_utc"]),
        ({"mission": {"start_time_utc": "9999-12-31T23:59:59Z"}}, ["mission", "start_time_utc"]),
        (
            {"scene": {**RESCUE, "bounds": {**RESCUE["bounds"], "position_high": [12, 5.5, INF]}}},
            ["scene", "bounds", "position_high", 2],
        ),
        ({"planner": {"seed": 2**64}}, ["planner", "seed"]),
        ({"planner": {"seed": True}}, ["planner", "seed"]),
        ({"system": {"platform_mass": 1e308}}, ["system", "platform_mass"]),
        ({"start": [0, 0, INF, 0, 0, 0, 1, 1, 1]}, ["start", 2]),
        ({"name": "bridge\x00"}, ["name"]),
    ],
)
def test_bad_numbers_are_refused_before_planning(client, body, location):
    response = client.post("/v1/tasks", content=_json(body), headers=_JSON)
    assert_refused(response, ["body", *location])


def test_the_offset_of_a_listing_is_bounded(client):
    response = client.get("/v1/tasks", params={"offset": 2**63})
    assert response.status_code == 422 and response.json()["detail"][0]["loc"][-1] == "offset"


def test_an_empty_listing_parameter_is_as_if_left_out(client):
    """``GET /v1/tasks?status=`` (as the README's table writes the parameters) lists every
    task, as if the parameter were left out; a status that is none is still refused, naming
    the parameter and the statuses there are."""
    from service.storage import TaskStatus

    store = client.app.state.service.store
    for status in (TaskStatus.FAILED, TaskStatus.CANCELLED):
        record = store.create({"name": f"listed {status.value}"})
        store.finish(record.id, record.attempt, status, None, "x")
    everything, _ = store.list(limit=500)
    for query in ("status=", "status=&offset=&limit=", "offset=&limit="):
        page = client.get(f"/v1/tasks?{query}")
        assert page.status_code == 200, (query, page.text)
        listed = page.json()
        assert listed["total"] == len(everything) >= 2, query
        assert (listed["offset"], listed["limit"]) == (0, 50), query
        assert [t["id"] for t in listed["items"]] == [r.id for r in everything[:50]], query
    failed = client.get("/v1/tasks?status=failed").json()["items"]
    assert failed and all(t["status"] == "failed" for t in failed)
    wrong = client.get("/v1/tasks?status=finished")
    assert wrong.status_code == 422
    (problem,) = wrong.json()["detail"]
    assert problem["loc"] == ["query", "status"]
    assert all(f"'{status.value}'" in problem["msg"] for status in TaskStatus), problem


def test_a_chunked_body_over_the_limit_is_413(client):
    def chunks():
        for _ in range(30):
            yield b" " * 1000  # 30 kB of whitespace against a 20 kB limit, no Content-Length

    response = client.post("/v1/tasks", content=chunks(), headers=_JSON)
    assert response.status_code == 413 and "larger than 20000 bytes" in response.text


def _json(body: dict) -> bytes:
    import json

    return json.dumps(body).encode()  # Python's json writes inf as Infinity, as attackers did


_JSON = {"content-type": "application/json"}


# -- item 8: missing or corrupt artifact files ----------------------------------------------


@pytest.fixture
def done_without_files(client):
    """A task recorded done whose artifact files are then missing or corrupt."""
    from service.storage import TaskStatus

    state = client.app.state.service
    record = state.store.create({"name": "files gone"})
    names = {f"drone{k}": f"drone{k}.mission.json" for k in (1, 2, 3)}
    names["summary"] = "summary.json"
    result = {"artifacts": names}
    state.store.finish(record.id, record.attempt, TaskStatus.DONE, result, None)
    folder = state.jobs.task_dir(record.id)
    folder.mkdir(parents=True)
    (folder / "drone1.mission.json").write_text("{ not json")
    (folder / "drone2.mission.json").write_text("[]")
    return record.id


def test_a_missing_artifact_file_is_404_and_a_corrupt_one_409(client, done_without_files):
    task = done_without_files
    missing = client.get(f"/v1/tasks/{task}/artifacts/summary.json")
    assert missing.status_code == 404 and "missing on disk" in missing.json()["detail"]
    assert client.get(f"/v1/tasks/{task}/bundle.zip").status_code == 404
    vehicles = [f"udpout:127.0.0.1:{14550 + k}" for k in range(3)]
    upload = client.post(f"/v1/tasks/{task}/upload", json={"vehicles": vehicles})
    assert upload.status_code == 409 and "drone1.mission.json" in upload.json()["detail"]


# -- item 6: the upload allow-list ----------------------------------------------------------


@pytest.fixture(scope="module")
def unfinished_task(client):
    """A task that exists but is not done: an allowed address gets 409, a refused one 403."""
    state = client.app.state.service
    return state.store.create({"name": "never run"}).id


@pytest.mark.parametrize(
    ("address", "status"),
    [
        ("udpout:127.0.0.999:14550", 403),  # not an address: went to the resolver
        ("udpout:127.0.0.256:14550", 403),
        ("udpout:127.\u0660.\u0660.\u0661:14550", 403),  # Arabic-Indic digits
        ("udpout:localhost:14550", 403),  # names are never resolved for the check
        ("udpout:10.0.0.1:14550", 403),
        ("/dev/tty0", 403),  # consoles
        ("/dev/ttyS0", 403),
        ("serial:/dev/tty1:57600", 403),
        ("udpout:127.0.0.1:\u0661\u0664\u0665\u0665\u0660", 422),  # Arabic-Indic digits
        ("udpout:127.0.0.1:14550", 409),  # allowed: the task is not done
        ("tcp:127.1.2.3:5760", 409),
        ("/dev/ttyUSB0:57600", 409),
        ("/dev/ttyACM1,115200", 409),
        ("/dev/serial/by-id/usb-ArduPilot_fmuv3_1E0037-if00", 409),
    ],
)
def test_only_loopback_addresses_and_named_serial_devices_are_allowed(
    client, unfinished_task, address, status
):
    others = ["udpout:127.0.0.1:15001", "udpout:127.0.0.1:15002"]
    response = client.post(
        f"/v1/tasks/{unfinished_task}/upload", json={"vehicles": [address, *others]}
    )
    assert response.status_code == status, response.text


# -- item 4: the database off the event loop; busy means 503 --------------------------------


# -- item 5: hosts, returned URLs, retention ---------------------------------------------------


def test_requests_for_other_hosts_are_refused(client):
    response = client.get("/v1/tasks", headers={"host": "attacker.example"})
    assert response.status_code == 400
    assert client.get("/v1/tasks", headers={"host": f"{TEST_HOST}:8000"}).status_code == 200


@pytest.mark.parametrize("loopback", ["127.0.0.1:8000", "localhost", "[::1]:8000"])
def test_the_health_check_answers_on_loopback_whatever_the_allowed_hosts(tmp_path, loopback):
    """Behind a proxy (ALLOWED_HOSTS names the public host only) the Docker image's health
    check, on http://127.0.0.1:8000/healthz, got 400 "Invalid host header": the container
    was never healthy. /healthz answers this machine's names too; nothing else does."""
    with running_service(tmp_path, allowed_hosts=("crane.example.org",)) as client:
        assert client.get("/healthz", headers={"host": loopback}).status_code == 200
        assert client.get("/healthz", headers={"host": "crane.example.org"}).status_code == 200
        for path in ("/v1/tasks", "/metrics", "/openapi.json"):
            refused = client.get(path, headers={"host": loopback})
            assert refused.status_code == 400 and refused.text == "Invalid host header", path
        for host in ("evil.example", "127.0.0.1.evil.example", "localhost.evil.example"):
            assert client.get("/healthz", headers={"host": host}).status_code == 400, host
        # only the health check: the same path in another method is refused by its host
        assert client.post("/healthz", json={}, headers={"host": loopback}).status_code == 400


def test_returned_urls_use_the_public_url_behind_a_proxy(tmp_path):
    public = "https://crane.example.org/api/"
    with running_service(tmp_path, public_url=public) as client:
        task = client.app.state.service.store.create({"name": "x"})
        url = client.get(f"/v1/tasks/{task.id}").json()["url"]
        assert url == f"{public}v1/tasks/{task.id}"


def test_finished_tasks_past_their_retention_are_deleted_with_their_files(tmp_path):
    from service.storage import TaskStatus

    with running_service(tmp_path, retention_days=30) as client:
        store = client.app.state.service.store
        old, recent, running = (store.create({"name": n}) for n in ("old", "recent", "running"))
        for record in (old, recent):
            store.finish(record.id, record.attempt, TaskStatus.FAILED, None, "x")
        store.update(running.id, status=TaskStatus.PLANNING)
        folder = tmp_path / "tasks" / old.id
        folder.mkdir(parents=True)
        (folder / "summary.json").write_text("{}")
    with sqlite3.connect(tmp_path / "flycrane.db") as database:
        long_ago = (datetime.now(UTC) - timedelta(days=31)).isoformat()
        for task_id in (old.id, running.id):
            database.execute("UPDATE tasks SET updated_at = ? WHERE id = ?", (long_ago, task_id))
    with running_service(tmp_path, retention_days=30) as client:
        assert client.get(f"/v1/tasks/{old.id}").status_code == 404
        assert not folder.exists()
        assert client.get(f"/v1/tasks/{recent.id}").status_code == 200
        assert client.get(f"/v1/tasks/{running.id}").status_code == 200  # unfinished: kept
        client.delete(f"/v1/tasks/{running.id}")


# -- item 10: lifecycle ----------------------------------------------------------------------


def test_a_second_server_on_the_same_data_directory_is_refused(tmp_path):
    with running_service(tmp_path) as client:
        store = client.app.state.service.store
        from service.storage import TaskStatus

        running = store.create({"name": "the first server's"})
        store.update(running.id, status=TaskStatus.PLANNING, attempt=1)
        second = create_app(Settings(data_dir=tmp_path, workers=1, allowed_hosts=(TEST_HOST,)))
        with pytest.raises(Exception, match="in use by another server"):
            with TestClient(second):
                pass
        record = store.get(running.id)
        assert (record.status, record.attempt) == (TaskStatus.PLANNING, 1)  # not taken over
        store.update(running.id, status=TaskStatus.CANCELLED)


def test_timestamps_carry_their_timezone(client):
    record = client.app.state.service.store.create({"name": "when"})
    task = client.get(f"/v1/tasks/{record.id}").json()
    for field in ("created_at", "updated_at"):
        stamp = datetime.fromisoformat(task[field])
        assert stamp.utcoffset() == timedelta(0), task[field]


def test_openapi_documents_the_real_responses(client):
    paths = client.get("/openapi.json").json()["paths"]
    post = paths["/v1/tasks"]["post"]["responses"]
    assert {"202", "400", "401", "413", "422", "503"} <= set(post)
    upload = paths["/v1/tasks/{task_id}/upload"]["post"]["responses"]
    assert {"200", "401", "403", "404", "409", "413", "422", "502", "503"} <= set(upload)
    artifact = paths["/v1/tasks/{task_id}/artifacts/{name}"]["get"]["responses"]["200"]
    assert {"application/json", "text/plain", "image/png", "application/octet-stream"} <= set(
        artifact["content"]
    )
    bundle = paths["/v1/tasks/{task_id}/bundle.zip"]["get"]["responses"]["200"]
    assert set(bundle["content"]) == {"application/zip"}
    assert "text/plain" in paths["/metrics"]["get"]["responses"]["200"]["content"]
    assert "503" in paths["/healthz"]["get"]["responses"]


def test_a_cancel_while_generating_ends_cancelled(tmp_path, monkeypatch):
    """The job runs in a thread here (an in-process executor), so its pipeline can be held
    in "generating" until the cancel has been answered: no timing involved."""
    import missions.task.pipeline
    from tests.service.conftest import wait_finished

    generating, release = threading.Event(), threading.Event()

    def held_pipeline(task, out_dir, progress=None, should_stop=None, **_):
        progress("planning", None)
        progress("generating", None)
        generating.set()
        release.wait(60)
        return missions.task.directory.TaskOutcome("done", planner_status="exact_solution")

    monkeypatch.setattr(missions.task.pipeline, "run_task", held_pipeline)
    settings = Settings(data_dir=tmp_path, allowed_hosts=(TEST_HOST,))
    with ThreadPoolExecutor(1) as pool, TestClient(create_app(settings, pool)) as client:
        task_id = client.post("/v1/tasks", json={"name": "held"}).json()["id"]
        assert generating.wait(60)
        assert client.get(f"/v1/tasks/{task_id}").json()["status"] == "generating"
        assert client.delete(f"/v1/tasks/{task_id}").json()["cancel_requested"]
        release.set()
        task = wait_finished(client, task_id)
        assert task["status"] == "cancelled" and "generating" in task["error"]


def test_serve_refuses_an_open_address_without_a_token(tmp_path, capsys):
    """The secure default: loopback only, unless a token is set or the operator says so."""
    import argparse

    from service.cli import _cmd_serve

    args = argparse.Namespace(
        host="0.0.0.0",
        port=0,
        data_dir=str(tmp_path),
        workers=1,
        allow_unauthenticated=False,
        proxy_headers=False,
        forwarded_allow_ips="127.0.0.1",
    )
    assert _cmd_serve(args) == 2
    assert "without FLYCRANE_API_TOKEN" in capsys.readouterr().err
