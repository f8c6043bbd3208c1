"""Issue 22, item 6: a 422 lists the first problems and counts the others, so that no
request makes the server answer many times its own size (0.98 MB of overlapping spheres
got 9.46 MB back).

One test per path a 422 takes (service/errors.py): the schema (RequestValidationError),
field checks after it (InputError) and an invalid start (InvalidConfigurationError).
"""

from __future__ import annotations

import json

import pytest

from flycrane.world.scene import load_scene
from service.errors import MAX_LISTED_PROBLEMS
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
