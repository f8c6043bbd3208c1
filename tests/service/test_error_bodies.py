"""Issue 22, item 6: a 422 lists the first problems and counts the others, so that no
request makes the server answer many times its own size (0.98 MB of overlapping spheres
got 9.46 MB back).

One test per path a 422 takes (service/errors.py): the schema (RequestValidationError),
field checks after it (InputError) and an invalid start (InvalidConfigurationError).
"""

from __future__ import annotations

import json
import threading
from concurrent.futures import ThreadPoolExecutor

import pytest

from flycrane.world.scene import load_scene
from service.errors import MAX_LISTED_PROBLEMS, READ_PROBLEMS
from tests.service.conftest import running_service

RESCUE = load_scene("rescue")[0].model_dump(mode="json")
#: Enough problems that listing them all made the body several times the request's size.
COUNT = 1000
JSON = {"content-type": "application/json"}


@pytest.fixture(scope="module")
def client(tmp_path_factory):
    with running_service(tmp_path_factory.mktemp("error_bodies")) as c:
        yield c


def task_with(obstacles: list[dict]) -> bytes:
    scene = {**RESCUE, "obstacles": obstacles}
    return json.dumps({"scene": scene, "start": RESCUE["start"], "goal": RESCUE["goal"]}).encode()


def sphere(k: int, radius: float) -> dict:
    return {"kind": "sphere", "name": f"s{k}", "center": [0.0, 0.0, 0.45], "radius": radius}


def refused(client, raw: bytes, bounded: bool = True) -> list[dict]:
    before = client.get("/v1/tasks").json()["total"]
    response = client.post("/v1/tasks", content=raw, headers=JSON)
    assert response.status_code == 422, response.text[:2000]
    if bounded:  # the request's size bounds the answer's, with a wide margin
        assert len(response.content) < len(raw) / 10, (len(response.content), len(raw))
    assert client.get("/v1/tasks").json()["total"] == before  # nothing stored
    return response.json()["detail"]


def assert_counted(summary: dict, listed: int, total: int) -> None:
    assert summary["loc"] == ["body"] and summary["type"] == "too_many_problems"
    assert f"{total - listed} more" in summary["msg"] and f"{total} in all" in summary["msg"]


def test_a_start_inside_many_spheres_lists_the_first_contacts_and_counts_all(client):
    raw = task_with([sphere(k, 3.0) for k in range(COUNT)])
    detail = refused(client, raw)
    assert [d["loc"] for d in detail] == [["body", "start"]]
    message = detail[0]["msg"]
    assert message.startswith("drone 1 hits s0 (by")
    # every sphere touches the three drones, the cables and the footbridge: thousands
    listed = message.count(" hits ")
    assert listed == MAX_LISTED_PROBLEMS
    more = message.rsplit("; and ", 1)[1]
    assert more.endswith("in all)") and "more (" in more


def test_many_schema_errors_are_counted_not_all_listed(client):
    raw = task_with([sphere(k, -1.0) for k in range(COUNT)])
    detail = refused(client, raw)
    assert len(detail) == MAX_LISTED_PROBLEMS + 1
    first = detail[0]
    assert first["loc"] == ["body", "scene", "obstacles", 0, "radius"]
    assert "greater than 0" in first["msg"]
    assert_counted(detail[-1], MAX_LISTED_PROBLEMS, COUNT)


def test_many_field_problems_are_counted_not_all_listed(client):
    meshes = [{"kind": "mesh", "name": f"m{k}", "file": "/etc/passwd"} for k in range(COUNT)]
    detail = refused(client, task_with(meshes))
    assert len(detail) == MAX_LISTED_PROBLEMS + 1
    assert detail[0]["loc"] == ["body", "scene", "obstacles[0]", "file"]
    assert "mesh files cannot be referenced" in detail[0]["msg"]
    assert_counted(detail[-1], MAX_LISTED_PROBLEMS, COUNT)


def test_a_few_problems_are_all_listed(client):
    detail = refused(client, task_with([sphere(k, -1.0) for k in range(3)]), bounded=False)
    assert [d["loc"][3] for d in detail] == [0, 1, 2]


# -- a body of very many wrong items (under the size limit) ----------------------------------
#
# Every entry pydantic reports used to be made readable (and encoded) before the first twenty
# were kept, on the event loop: 450 000 wrong obstacles held every request up.


def test_half_a_million_wrong_items_are_counted_not_each_made_readable(client, monkeypatch):
    import service.errors

    made_readable: list[int] = []
    real = service.errors.readable_errors

    def counting(errors):
        errors = list(errors)
        made_readable.append(len(errors))
        return real(errors)

    monkeypatch.setattr(service.errors, "readable_errors", counting)
    wrong = 450_000
    raw = json.dumps(
        {"scene": {**RESCUE, "obstacles": [1] * wrong}}, separators=(",", ":")
    ).encode()
    assert len(raw) < 1_000_000  # under the default body limit: refused by its schema
    detail = refused(client, raw)
    assert len(detail) == MAX_LISTED_PROBLEMS + 1
    assert detail[0]["loc"] == ["body", "scene", "obstacles", 0]
    assert detail[MAX_LISTED_PROBLEMS - 1]["loc"][-1] == MAX_LISTED_PROBLEMS - 1
    assert_counted(detail[-1], MAX_LISTED_PROBLEMS, wrong)
    assert made_readable and max(made_readable) <= READ_PROBLEMS, made_readable


@pytest.mark.parametrize(
    ("path", "body", "location"),
    [
        ("/v1/tasks", {"scene": {**RESCUE, "obstacles": [1, 1, 1]}}, ["body", "scene"]),
        ("/v1/statics", {"q": [["x"] * 9] * 3}, ["body", "q"]),
        ("/v1/tasks/nope/upload", {"vehicles": ["udp:127.0.0.1:1"]}, ["body", "vehicles"]),
    ],
)
def test_a_body_is_refused_off_the_event_loop(client, monkeypatch, path, body, location):
    """The 422 is made while /healthz is answered: the refusal is held where it is made until
    the health check is back (if it were made on the event loop, the health check could not
    be answered, and the hold would end by its guard, not by the release)."""
    import service.errors

    entered, release, released = threading.Event(), threading.Event(), []
    real = service.errors.readable_errors

    def held(errors):
        entered.set()
        released.append(release.wait(60))
        return real(errors)

    monkeypatch.setattr(service.errors, "readable_errors", held)
    with ThreadPoolExecutor(1) as sender:
        answer = sender.submit(client.post, path, json=body)
        assert entered.wait(60)
        health = client.get("/healthz")
        release.set()
        response = answer.result()
    assert released == [True] and health.status_code == 200, health.text
    assert response.status_code == 422, response.text
    assert response.json()["detail"][0]["loc"][: len(location)] == location
