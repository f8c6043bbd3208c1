"""Cross-site requests: a page on another site can make a browser POST text/plain or form
bodies without a CORS preflight. Every POST must say ``Content-Type: application/json``,
else 415 naming the header, and nothing is queued."""

from __future__ import annotations

import threading
from concurrent.futures import ThreadPoolExecutor

import pytest
from fastapi.testclient import TestClient

from service.app import create_app
from service.settings import Settings
from tests.service.conftest import TEST_HOST

BODY = b'{"name": "cross-site"}'
EVIL = {"origin": "http://evil.example"}


@pytest.fixture
def client(tmp_path, monkeypatch):
    """The service, its tasks held (never planned) until the test ends."""
    import missions.task.pipeline

    release = threading.Event()
    monkeypatch.setattr(missions.task.pipeline, "run_task", lambda *a, **k: release.wait(60))
    settings = Settings(data_dir=tmp_path, allowed_hosts=(TEST_HOST,))
    with ThreadPoolExecutor(1) as pool, TestClient(create_app(settings, pool)) as client:
        yield client
        release.set()


def stored_tasks(client: TestClient) -> int:
    return client.get("/v1/tasks").json()["total"]


@pytest.mark.parametrize(
    "content_type",
    ["text/plain", "application/x-www-form-urlencoded", "multipart/form-data; boundary=x"],
)
@pytest.mark.parametrize("path", ["/v1/tasks", "/v1/statics", "/v1/tasks/nope/upload"])
def test_a_body_that_is_not_declared_json_is_415_naming_the_header(client, content_type, path):
    response = client.post(path, content=BODY, headers={**EVIL, "content-type": content_type})
    assert response.status_code == 415, response.text
    assert response.headers["content-type"] == "application/json"
    detail = response.json()["detail"]
    assert f"Content-Type is {content_type!r}" in detail and "application/json" in detail
    assert stored_tasks(client) == 0


def test_a_body_without_content_type_is_415(client):
    response = client.post("/v1/tasks", content=BODY, headers=EVIL)
    assert response.status_code == 415, response.text
    assert "Content-Type is missing" in response.json()["detail"]
    assert stored_tasks(client) == 0


def test_one_wrong_content_type_among_two_is_415(client):
    headers = [("content-type", "application/json"), ("content-type", "text/plain")]
    response = client.post("/v1/tasks", content=BODY, headers=headers)
    assert response.status_code == 415, response.text
    assert stored_tasks(client) == 0


@pytest.mark.parametrize(
    "content_type", ["application/json", "application/json; charset=utf-8", "Application/JSON"]
)
def test_json_is_accepted(client, content_type):
    response = client.post("/v1/tasks", content=BODY, headers={"content-type": content_type})
    assert response.status_code == 202, response.text
    task = client.get(f"/v1/tasks/{response.json()['id']}").json()
    assert task["name"] == "cross-site" and stored_tasks(client) == 1


def test_openapi_documents_the_415(client):
    responses = client.get("/openapi.json").json()["paths"]["/v1/tasks"]["post"]["responses"]
    assert "Content-Type" in responses["415"]["description"]
