"""The task store on SQLite and on a real PostgreSQL server, and its schema migrations.

Evidence independent of the ORM: the database created "before migrations" is made with
plain SQL DDL written here (the schema the service created with ``create_all`` up to
revision 0001), rows are inserted with plain SQL, and the schema after ``upgrade`` is
compared with the ORM's by Alembic's own comparison.
"""

from __future__ import annotations

import json
import threading
from datetime import UTC, datetime, timedelta

import pytest
from alembic.autogenerate import compare_metadata
from alembic.runtime.migration import MigrationContext
from sqlalchemy import inspect, text
from sqlalchemy.engine import Engine

from service.migrate import current_revision, head_revision, upgrade_database
from service.storage import TaskStatus, TaskStore, make_engine, metadata

#: The tables as the service created them before it had migrations (SQLite and PostgreSQL).
PRE_MIGRATION_DDL = {
    "sqlite": [
        """CREATE TABLE tasks (id VARCHAR(32) NOT NULL, status VARCHAR(16) NOT NULL,
           created_at DATETIME NOT NULL, updated_at DATETIME NOT NULL, request JSON NOT NULL,
           progress JSON, result JSON, error TEXT, cancel_requested BOOLEAN NOT NULL,
           attempt INTEGER NOT NULL, PRIMARY KEY (id))""",
        "CREATE INDEX ix_tasks_status ON tasks (status)",
        """CREATE TABLE uploads (id INTEGER NOT NULL, task_id VARCHAR(32) NOT NULL,
           created_at DATETIME NOT NULL, outcome JSON NOT NULL, PRIMARY KEY (id),
           FOREIGN KEY(task_id) REFERENCES tasks (id))""",
        "CREATE INDEX ix_uploads_task_id ON uploads (task_id)",
    ],
    "postgresql": [
        """CREATE TABLE tasks (id VARCHAR(32) NOT NULL, status VARCHAR(16) NOT NULL,
           created_at TIMESTAMP WITH TIME ZONE NOT NULL,
           updated_at TIMESTAMP WITH TIME ZONE NOT NULL, request JSON NOT NULL,
           progress JSON, result JSON, error TEXT, cancel_requested BOOLEAN NOT NULL,
           attempt INTEGER NOT NULL, PRIMARY KEY (id))""",
        "CREATE INDEX ix_tasks_status ON tasks (status)",
        """CREATE TABLE uploads (id SERIAL NOT NULL, task_id VARCHAR(32) NOT NULL,
           created_at TIMESTAMP WITH TIME ZONE NOT NULL, outcome JSON NOT NULL,
           PRIMARY KEY (id), FOREIGN KEY(task_id) REFERENCES tasks (id))""",
        "CREATE INDEX ix_uploads_task_id ON uploads (task_id)",
    ],
}


@pytest.fixture
def engine(backend, database_url, tmp_path) -> Engine:
    url = database_url or f"sqlite:///{tmp_path / 'flycrane.db'}"
    engine = make_engine(url)
    yield engine
    engine.dispose()


@pytest.fixture
def store(engine) -> TaskStore:
    upgrade_database(engine)
    return TaskStore(engine)


def schema_differences(engine: Engine) -> list:
    with engine.connect() as connection:
        return compare_metadata(MigrationContext.configure(connection), metadata)


def test_an_empty_database_is_upgraded_to_the_orm_schema(engine):
    assert current_revision(engine) is None
    assert upgrade_database(engine) == head_revision()
    assert current_revision(engine) == head_revision()
    assert schema_differences(engine) == []
    assert upgrade_database(engine) == head_revision()  # again: nothing to do


def test_a_database_from_before_migrations_keeps_its_rows(backend, engine):
    created = datetime(2026, 11, 20, 12, 0, tzinfo=UTC)
    request = {"name": "kept", "scene": "rescue"}
    with engine.begin() as connection:
        for statement in PRE_MIGRATION_DDL[backend]:
            connection.execute(text(statement))
        connection.execute(
            text(
                "INSERT INTO tasks (id, status, created_at, updated_at, request, result, "
                "cancel_requested, attempt) VALUES ('a' , 'done', :t, :t, :request, :result, "
                "false, 1)"
            ),
            {"t": created, "request": json.dumps(request), "result": json.dumps({"ok": 1})},
        )
        connection.execute(
            text("INSERT INTO uploads (task_id, created_at, outcome) VALUES ('a', :t, :o)"),
            {"t": created, "o": json.dumps({"ok": True})},
        )
    assert "alembic_version" not in inspect(engine).get_table_names()
    upgrade_database(engine)
    assert current_revision(engine) == head_revision()
    assert schema_differences(engine) == []
    store = TaskStore(engine)
    record = store.get("a")
    assert record is not None
    assert (record.status, record.request, record.result) == (TaskStatus.DONE, request, {"ok": 1})
    assert record.created_at == created and record.created_at.tzinfo is not None
    assert store.uploads("a")[0]["ok"] is True


def test_tasks_round_trip_with_their_json_and_timestamps(store):
    first = store.create({"name": "one", "nested": {"list": [1.5, None, "x"]}})
    second = store.create({"name": "two"})
    store.update(first.id, status=TaskStatus.PLANNING, progress={"nodes": 3})
    record = store.get(first.id)
    assert record.status is TaskStatus.PLANNING and record.progress == {"nodes": 3}
    assert record.request == {"name": "one", "nested": {"list": [1.5, None, "x"]}}
    assert record.updated_at.tzinfo is not None and record.updated_at >= record.created_at
    page, total = store.list(offset=0, limit=10)
    assert total == 2 and {r.id for r in page} == {first.id, second.id}
    assert store.list(TaskStatus.PLANNING)[1] == 1
    assert store.counts_by_status()["queued"] == 1


def test_a_cancel_racing_a_finish_ends_cancelled_and_a_stale_attempt_writes_nothing(store):
    task = store.create({"name": "racing"})
    store.update(task.id, status=TaskStatus.GENERATING, attempt=2)
    store.update(task.id, cancel_requested=True)
    finished = store.finish(task.id, 2, TaskStatus.DONE, {"ok": 1}, None)
    assert finished.status is TaskStatus.CANCELLED
    assert finished.error == "cancelled while generating the missions"
    other = store.create({"name": "superseded"})
    store.update(other.id, attempt=3)
    store.finish(other.id, 2, TaskStatus.DONE, {"ok": 1}, None)
    assert store.get(other.id).status is TaskStatus.QUEUED


def test_concurrent_updates_from_threads_lose_nothing(store):
    tasks = [store.create({"name": f"t{i}"}) for i in range(8)]

    def work(task_id: str) -> None:
        for step in range(10):
            store.update(task_id, progress={"step": step})
        store.finish(task_id, 0, TaskStatus.DONE, {"id": task_id}, None)

    threads = [threading.Thread(target=work, args=(t.id,)) for t in tasks]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join(timeout=60)
    for task in tasks:
        record = store.get(task.id)
        assert record.status is TaskStatus.DONE and record.result == {"id": task.id}
        assert record.progress == {"step": 9}


def test_purge_deletes_finished_tasks_with_their_uploads_and_files(store, tmp_path):
    old = store.create({"name": "old"})
    store.finish(old.id, 0, TaskStatus.DONE, {}, None)
    store.add_upload(old.id, {"ok": True})
    running = store.create({"name": "running"})
    (tmp_path / "tasks" / old.id).mkdir(parents=True)
    purged = store.purge(datetime.now(UTC) + timedelta(seconds=1), tmp_path / "tasks")
    assert purged == [old.id]
    assert store.get(old.id) is None and store.uploads(old.id) == []
    assert store.get(running.id) is not None
    assert not (tmp_path / "tasks" / old.id).exists()
