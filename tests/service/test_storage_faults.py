"""Issue 22, item 7: the disk fills while a task generates its missions.

Before: the task stayed ``generating`` for ever (recording the failure failed too),
``/healthz`` said ok, DELETE answered 200 and changed nothing, and freeing space did not
help. Now the outcome is kept and written once the database takes writes again, the health
check reports the state meanwhile, and cancel ends a task no job runs any more.

The job runs on a thread of the test process (an executor the test owns), so that the fault
reaches it: every INSERT, UPDATE and DELETE fails as SQLite fails on a full disk while the
fault is on. The pipeline is replaced by one that reports its stages and then fails writing
an artifact, as a full disk makes it fail; nothing is planned.
"""

from __future__ import annotations

import errno
import sqlite3
import threading
import time
from collections.abc import Iterator
from concurrent.futures import ThreadPoolExecutor
from contextlib import contextmanager

import pytest
from fastapi.testclient import TestClient
from sqlalchemy import event
from sqlalchemy.engine import Engine

import missions.task.pipeline
from service.app import create_app
from service.jobs import JobManager
from service.settings import Settings
from tests.service.conftest import TEST_HOST, wait_status

#: Generous for a loaded 2-core machine (the behaviour, not the speed, is under test).
WITHIN = 30.0
WRITES = ("INSERT", "UPDATE", "DELETE")


class FullDisk:
    """While on, every write on every engine fails with SQLite's "database or disk is full"."""

    def __init__(self) -> None:
        self.on = threading.Event()

    def _refuse(self, _conn, _cursor, statement: str, *_args) -> None:
        if self.on.is_set() and statement.lstrip()[:6].upper() in WRITES:
            raise sqlite3.OperationalError("database or disk is full")

    def __enter__(self) -> FullDisk:
        event.listen(Engine, "before_cursor_execute", self._refuse)
        return self

    def __exit__(self, *exc: object) -> None:
        event.remove(Engine, "before_cursor_execute", self._refuse)


class Pipeline:
    """Stands in for run_task: planning, then generating, then (once the disk is full) an
    artifact that cannot be written."""

    def __init__(self) -> None:
        self.generating, self.disk_full = threading.Event(), threading.Event()

    def __call__(self, task, task_dir, progress, should_stop):
        progress("planning", None)
        progress("generating", None)
        self.generating.set()
        assert self.disk_full.wait(WITHIN)
        raise OSError(errno.ENOSPC, "No space left on device", str(task_dir / "tracks.json"))


@contextmanager
def service(tmp_path, monkeypatch) -> Iterator[tuple[TestClient, FullDisk, Pipeline]]:
    pipeline = Pipeline()
    monkeypatch.setattr(missions.task.pipeline, "run_task", pipeline)
    settings = Settings(data_dir=tmp_path, workers=1, allowed_hosts=(TEST_HOST,))
    with ThreadPoolExecutor(1, thread_name_prefix="job") as executor, FullDisk() as disk:
        try:
            with TestClient(create_app(settings, executor)) as client:
                yield client, disk, pipeline
        finally:
            pipeline.disk_full.set()  # a job still waiting ends
            disk.on.clear()


def fill_the_disk_while_generating(client, disk, pipeline) -> str:
    accepted = client.post("/v1/tasks", json={"name": "disk full"})
    assert accepted.status_code == 202, accepted.text
    task = accepted.json()["id"]
    assert pipeline.generating.wait(WITHIN)
    disk.on.set()
    pipeline.disk_full.set()
    return task


def wait_health(client, status: int) -> dict:
    deadline = time.monotonic() + WITHIN
    while (health := client.get("/healthz")).status_code != status:
        assert time.monotonic() < deadline, health.text
        time.sleep(0.1)
    return health.json()


def test_a_task_failing_on_a_full_disk_ends_failed_once_writing_works(tmp_path, monkeypatch):
    with service(tmp_path, monkeypatch) as (client, disk, pipeline):
        task = fill_the_disk_while_generating(client, disk, pipeline)
        health = wait_health(client, 503)
        assert any("database or disk is full" in p for p in health["problems"]), health
        assert client.get(f"/v1/tasks/{task}").json()["status"] == "generating"
        refused = client.delete(f"/v1/tasks/{task}")  # cannot be recorded: say so
        assert refused.status_code == 503 and "retry-after" in refused.headers
        assert "database or disk is full" in refused.json()["detail"]
        disk.on.clear()  # space freed
        ended = wait_status(client, task, {"done", "failed", "cancelled"}, WITHIN)
        assert ended["status"] == "failed", ended
        assert "No space left on device" in ended["error"]
        assert wait_health(client, 200)["problems"] == []


def test_cancel_ends_a_task_no_job_runs_any_more(tmp_path, monkeypatch):
    monkeypatch.setattr(JobManager, "reconcile_interval", 3600.0)  # only the cancel acts
    with service(tmp_path, monkeypatch) as (client, disk, pipeline):
        task = fill_the_disk_while_generating(client, disk, pipeline)
        wait_health(client, 503)
        disk.on.clear()
        cancelled = client.delete(f"/v1/tasks/{task}")
        assert cancelled.status_code == 200, cancelled.text
        assert cancelled.json()["status"] == "cancelled", cancelled.json()
        assert client.get(f"/v1/tasks/{task}").json()["status"] == "cancelled"
        assert wait_health(client, 200)["problems"] == []


@pytest.mark.parametrize("stage", ["planning", "generating"])
def test_cancel_ends_a_task_left_running_without_a_job(tmp_path, monkeypatch, stage):
    """A row that says running, and no job of this server runs it (one that ended without
    recording how): cancel ends it at once instead of waiting for a job that never comes."""
    with service(tmp_path, monkeypatch) as (client, _, _):
        state = client.app.state.service
        record = state.store.create({"name": "orphan"})
        state.store.update(record.id, status=stage)
        cancelled = client.delete(f"/v1/tasks/{record.id}")
        assert cancelled.status_code == 200 and cancelled.json()["status"] == "cancelled"
