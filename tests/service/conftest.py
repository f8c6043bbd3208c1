"""A real application (real worker processes) on a temporary data directory."""

from __future__ import annotations

import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from fastapi.testclient import TestClient

from service.app import create_app
from service.settings import Settings

FINISHED = {"done", "failed", "cancelled"}
#: The Host header of starlette's TestClient.
TEST_HOST = "testserver"


@contextmanager
def running_service(
    data_dir: Path, database_url: str | None = None, **settings
) -> Iterator[TestClient]:
    """The service with its lifespan (database, worker pool, resumption) running, on the
    database at ``database_url`` (default: SQLite in ``data_dir``)."""
    settings.setdefault("allowed_hosts", (TEST_HOST,))
    if database_url is not None:
        settings["database_url"] = database_url
    app = create_app(Settings(data_dir=data_dir, workers=1, **settings))
    with TestClient(app) as client:
        yield client


def wait_finished(client: TestClient, task_id: str, timeout: float = 120.0) -> dict:
    """Poll a task until it is done, failed or cancelled."""
    return wait_status(client, task_id, FINISHED, timeout, poll=0.3)


def wait_status(
    client: TestClient, task_id: str, statuses: set[str], timeout: float = 60.0, poll: float = 0.1
) -> dict:
    """Poll a task until its status is one of ``statuses``."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        task = client.get(f"/v1/tasks/{task_id}").json()
        if task["status"] in statuses:
            return task
        time.sleep(poll)
    raise AssertionError(f"task {task_id} never reached {statuses} in {timeout} s: {task}")


def wait_progress(client, task_id: str, timeout: float = 60.0) -> dict:
    """The first progress report with planner figures (written every 0.5 s)."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        progress = client.get(f"/v1/tasks/{task_id}").json()["progress"] or {}
        if "nodes" in progress:
            return progress
        time.sleep(0.1)
    raise AssertionError(f"no planner progress for {task_id}")
