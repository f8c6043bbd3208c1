"""Issue 22, items 7 and 8: storage that cannot take writes, mid-task and at start.

Item 7, the disk fills while a task generates its missions.

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
import os
import shutil
import signal
import socket
import sqlite3
import subprocess
import sys
import threading
import time
from collections.abc import Iterator
from concurrent.futures import ThreadPoolExecutor
from contextlib import contextmanager
from pathlib import Path

import pytest
from fastapi.testclient import TestClient
from sqlalchemy import create_engine, event
from sqlalchemy.engine import Engine

import missions.task.pipeline
from service.app import create_app
from service.errors import StartupError
from service.jobs import JobManager
from service.settings import Settings
from service.startup import check_database
from service.storage import TaskStatus
from tests.service.conftest import TEST_HOST, wait_status
from tests.service.test_serve import ROOT, clean_environment, free_port, serve_command

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


# -- item 8: storage that cannot work, at start ----------------------------------------------
#
# Before: a full disk or a corrupt file ended the start in a 140-line traceback, a database
# with corrupt interior pages started and took tasks, a read-only one started healthy and
# answered every POST "retry later". Now the start is refused with one line naming the file
# and the reason; through the lifespan (StartupError) and through `flycrane serve` (exit 1).
# The files are real: a database written by the service, then garbage over its pages, made
# read-only, or put on a full file system (a tmpfs in a private mount namespace).

SQLITE_PAGE = 4096
#: A refused start ends well within this (a start that is not refused runs until killed).
REFUSED_WITHIN = 90.0
LIFESPAN = """
import sys
from pathlib import Path
from fastapi.testclient import TestClient
from service.app import create_app
from service.settings import Settings
settings = Settings(data_dir=Path(sys.argv[1]), workers=1, allowed_hosts=("testserver",))
try:
    with TestClient(create_app(settings)) as client:
        print("started", client.get("/healthz").status_code)
except Exception as error:
    print(f"refused {type(error).__name__}: {error}")
"""


def stored_history(data_dir: Path) -> Path:
    """A data directory as a server leaves it: done tasks, each with uploads; its database."""
    settings = Settings(data_dir=data_dir, workers=1, allowed_hosts=(TEST_HOST,))
    with TestClient(create_app(settings)) as client:
        store = client.app.state.service.store
        for k in range(20):
            record = store.create({"name": f"task {k}"})
            store.finish(record.id, record.attempt, TaskStatus.DONE, {}, None)
            for _ in range(5):
                store.add_upload(record.id, {"ok": True, "vehicles": [{"detail": "u" * 600}]})
    database = data_dir / "flycrane.db"
    assert not database.with_name("flycrane.db-wal").exists()  # all in the file
    return database


def pages_of(database: Path, table: str, kind: str) -> list[int]:
    """Page numbers (1-based) of a table's b-tree pages of a kind (SQLite's dbstat)."""
    connection = sqlite3.connect(database)
    try:
        query = "SELECT pageno FROM dbstat WHERE name = ? AND pagetype = ? ORDER BY pageno"
        return [row[0] for row in connection.execute(query, (table, kind))]
    finally:
        connection.close()


def overwrite(database: Path, start: int, end: int, byte: int = 0x5A) -> None:
    raw = bytearray(database.read_bytes())
    raw[start:end] = bytes([byte]) * (end - start)
    database.write_bytes(bytes(raw))


def corrupt(database: Path, how: str) -> str:
    """Write garbage over part of the file; what SQLite says about such a file."""
    if how == "header":
        overwrite(database, 0, 100)
        return "file is not a database"
    if how == "schema":
        overwrite(database, 100, SQLITE_PAGE)
        return "malformed"
    leaves = pages_of(database, "uploads", "leaf")  # interior: nothing reads them at start
    page = leaves[len(leaves) // 2]
    overwrite(database, (page - 1) * SQLITE_PAGE, page * SQLITE_PAGE)
    return "malformed"


def start_in_process(data_dir: Path) -> None:
    settings = Settings(data_dir=data_dir, workers=1, allowed_hosts=(TEST_HOST,))
    with TestClient(create_app(settings)) as client:
        assert client.post("/v1/tasks", json={"scene": "atlantis"}).status_code == 422


@pytest.mark.parametrize("how", ["header", "schema", "interior"])
def test_a_corrupt_database_is_refused_at_start_through_the_lifespan(tmp_path, how):
    database = stored_history(tmp_path)
    says = corrupt(database, how)
    with pytest.raises(StartupError) as refused:
        start_in_process(tmp_path)
    message = str(refused.value)
    assert "\n" not in message and str(database) in message and says in message, message


def test_a_database_server_that_cannot_be_reached_is_named_with_server_advice():
    """Not the advice for a file (writable, disk space), and never the password."""
    with socket.socket() as probe:  # a loopback port nothing listens on
        probe.bind(("127.0.0.1", 0))
        port = probe.getsockname()[1]
    engine = create_engine(f"postgresql+psycopg://crane:hunter2@127.0.0.1:{port}/tasks")
    with pytest.raises(StartupError) as refused:
        check_database(engine)
    message = str(refused.value)
    assert f"127.0.0.1:{port}/tasks cannot be used" in message, message
    assert "its server runs and can be reached" in message and "writable" not in message
    assert "hunter2" not in message and "\n" not in message


def test_a_sound_database_starts(tmp_path):
    stored_history(tmp_path)
    start_in_process(tmp_path)  # the checks pass and leave nothing behind
    start_in_process(tmp_path)


def serve_refused(command: list[str], data_dir: Path) -> str:
    """Run ``command`` (ending in ``flycrane serve``); its one line on stderr, asserting it
    refused to start (a server that starts is killed, and the test fails)."""
    process = subprocess.Popen(
        command,
        cwd=ROOT,
        env=clean_environment(),
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        start_new_session=True,
    )
    try:
        _, err = process.communicate(timeout=REFUSED_WITHIN)
    except subprocess.TimeoutExpired:
        os.killpg(process.pid, signal.SIGKILL)
        _, err = process.communicate()
        pytest.fail(f"started instead of refusing: {err[-3000:]}")
    assert process.returncode == 1, (process.returncode, err[-3000:])
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("flycrane serve: "), err[-3000:]
    assert str(data_dir) in lines[0], lines[0]
    return lines[0]


def serve(data_dir: Path) -> list[str]:
    port = free_port(socket.AF_INET, "127.0.0.1")
    return serve_command(data_dir, "--port", str(port), "--workers", "1")


def lifespan(data_dir: Path) -> list[str]:
    return [sys.executable, "-c", LIFESPAN, str(data_dir)]


def lifespan_refused(command: list[str]) -> str:
    run = subprocess.run(
        command,
        cwd=ROOT,
        env=clean_environment(),
        capture_output=True,
        text=True,
        timeout=REFUSED_WITHIN,
        check=False,
    )
    assert run.stdout.startswith("refused StartupError: "), run.stdout + run.stderr[-3000:]
    return run.stdout.strip()


@pytest.mark.parametrize("how", ["header", "interior"])
def test_flycrane_serve_refuses_a_corrupt_database_in_one_line(tmp_path, how):
    database = stored_history(tmp_path / "data")
    says = corrupt(database, how)
    line = serve_refused(serve(tmp_path / "data"), tmp_path / "data")
    assert (says in line and "corrupt" in line) or "not a database" in line, line


def unprivileged() -> list[str]:
    """A prefix that makes file permissions bind: root keeps its uid, loses its capabilities
    (CAP_DAC_OVERRIDE would let it write anything)."""
    if os.geteuid() != 0:
        return []
    if shutil.which("setpriv") is None:
        pytest.skip("running as root without util-linux setpriv: permissions cannot bind")
    return ["setpriv", "--bounding-set=-all", "--inh-caps=-all", "--"]


@pytest.mark.parametrize("where", ["file", "directory"])
def test_a_read_only_database_is_refused_at_start(tmp_path, where):
    data_dir = tmp_path / "data"
    database = stored_history(data_dir)
    (database if where == "file" else data_dir).chmod(0o444 if where == "file" else 0o555)
    try:
        says = "readonly database" if where == "file" else "Permission denied"
        line = serve_refused([*unprivileged(), *serve(data_dir)], data_dir)
        assert says in line, line
        if where == "file":  # started healthy, then answered every POST "retry later"
            assert says in lifespan_refused([*unprivileged(), *lifespan(data_dir)])
    finally:
        data_dir.chmod(0o755)
        database.chmod(0o644)


def on_a_full_disk(data_dir: Path, command: list[str]) -> list[str]:
    """``command`` where ``data_dir`` is a copy of itself on a file system with no space
    left: a small tmpfs mounted over it in a private mount namespace, then filled."""
    probe = subprocess.run(
        ["unshare", "--mount", "--propagation", "private", "mount", "-t", "tmpfs", "x", "/mnt"],
        capture_output=True,
        check=False,
    )
    if probe.returncode != 0:
        pytest.skip(f"no private mount namespace here: {probe.stderr.decode().strip()}")
    staged = data_dir.with_name("staged")
    shutil.copytree(data_dir, staged)
    script = (
        'mount -t tmpfs -o size=1m tmpfs "$1" && cp -a "$2/." "$1/" '
        '&& { dd if=/dev/zero of="$1/filler" bs=4k 2>/dev/null; true; } && shift 2 && exec "$@"'
    )
    unshare = ["unshare", "--mount", "--propagation", "private", "sh", "-c", script, "sh"]
    return [*unshare, str(data_dir), str(staged), *command]


def test_a_full_disk_is_refused_at_start(tmp_path):
    data_dir = tmp_path / "data"
    stored_history(data_dir)
    line = serve_refused(on_a_full_disk(data_dir, serve(data_dir)), data_dir)
    assert "No space left on device" in line, line
    shutil.rmtree(data_dir.with_name("staged"))
    assert "No space left" in lifespan_refused(on_a_full_disk(data_dir, lifespan(data_dir)))
