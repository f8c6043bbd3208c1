"""Persistent task records through SQLAlchemy (SQLite by default, PostgreSQL by URL).

A task row is written before the service answers 202, and every status change is a
committed transaction, so a restart finds every task where it was. Artifacts are files in
``<data_dir>/tasks/<task id>/`` (see :mod:`service.artifacts`); the row stores their names.
"""

from __future__ import annotations

import builtins
import enum
import shutil
import uuid
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

from sqlalchemy import (
    JSON,
    Boolean,
    DateTime,
    ForeignKey,
    Integer,
    String,
    Text,
    case,
    create_engine,
    delete,
    event,
    func,
    select,
    update,
)
from sqlalchemy.engine import Dialect, Engine
from sqlalchemy.exc import SQLAlchemyError
from sqlalchemy.orm import DeclarativeBase, Mapped, Session, mapped_column, sessionmaker
from sqlalchemy.types import TypeDecorator

#: Largest listing offset: far beyond any number of tasks, well inside SQLite's integers.
MAX_OFFSET = 1_000_000_000


class TaskStatus(enum.StrEnum):
    """Life cycle of a task."""

    QUEUED = "queued"
    PLANNING = "planning"
    GENERATING = "generating"
    DONE = "done"
    FAILED = "failed"
    CANCELLED = "cancelled"

    @property
    def finished(self) -> bool:
        return self in (TaskStatus.DONE, TaskStatus.FAILED, TaskStatus.CANCELLED)


def _now() -> datetime:
    return datetime.now(UTC)


class UtcDateTime(TypeDecorator[datetime]):
    """Timestamps stored in UTC and read back timezone-aware: SQLite keeps no zone, and a
    naive time in the API would be read as the client's local time."""

    impl = DateTime(timezone=True)
    cache_ok = True

    def process_bind_param(self, value: datetime | None, dialect: Dialect) -> datetime | None:
        if value is None:
            return None
        if value.tzinfo is None:
            raise ValueError("naive datetime: give a timezone")
        return value.astimezone(UTC)

    def process_result_value(self, value: datetime | None, dialect: Dialect) -> datetime | None:
        if value is None:
            return None
        return value.replace(tzinfo=UTC) if value.tzinfo is None else value.astimezone(UTC)


class _Base(DeclarativeBase):
    pass


#: The tables as the code reads them; ``service/migrations`` makes a database match them.
metadata = _Base.metadata


class TaskRow(_Base):
    __tablename__ = "tasks"

    id: Mapped[str] = mapped_column(String(32), primary_key=True)
    status: Mapped[str] = mapped_column(String(16), index=True)
    created_at: Mapped[datetime] = mapped_column(UtcDateTime, default=_now)
    updated_at: Mapped[datetime] = mapped_column(UtcDateTime, default=_now)
    request: Mapped[dict] = mapped_column(JSON)
    progress: Mapped[dict | None] = mapped_column(JSON, nullable=True)
    result: Mapped[dict | None] = mapped_column(JSON, nullable=True)
    error: Mapped[str | None] = mapped_column(Text, nullable=True)
    cancel_requested: Mapped[bool] = mapped_column(Boolean, default=False)
    #: Incremented each time the task is (re)queued; a job only writes while its attempt is
    #: current, so a job orphaned by a restart cannot overwrite its successor's results.
    attempt: Mapped[int] = mapped_column(Integer, default=0)


class UploadRow(_Base):
    __tablename__ = "uploads"

    id: Mapped[int] = mapped_column(Integer, primary_key=True, autoincrement=True)
    task_id: Mapped[str] = mapped_column(ForeignKey("tasks.id"), index=True)
    created_at: Mapped[datetime] = mapped_column(UtcDateTime, default=_now)
    outcome: Mapped[dict] = mapped_column(JSON)


@dataclass(frozen=True)
class TaskRecord:
    """A task as plain data (what the API and the job manager pass around)."""

    id: str
    status: TaskStatus
    created_at: datetime
    updated_at: datetime
    request: dict[str, Any]
    progress: dict[str, Any] | None
    result: dict[str, Any] | None
    error: str | None
    cancel_requested: bool
    attempt: int

    @classmethod
    def of(cls, row: TaskRow) -> TaskRecord:
        return cls(
            id=row.id,
            status=TaskStatus(row.status),
            created_at=row.created_at,
            updated_at=row.updated_at,
            request=row.request,
            progress=row.progress,
            result=row.result,
            error=row.error,
            cancel_requested=row.cancel_requested,
            attempt=row.attempt,
        )


def database_reason(failure: SQLAlchemyError) -> str:
    """The database's own words (its driver's first line), without SQLAlchemy's statement,
    parameters and link."""
    text = str(getattr(failure, "orig", None) or failure)
    return text.splitlines()[0] if text else type(failure).__name__


def make_engine(url: str, busy_timeout: float = 30.0) -> Engine:
    """An engine for ``url``; SQLite gets WAL so readers do not block the writer, and waits
    at most ``busy_timeout`` [s] for a lock before the statement fails (the API answers 503)."""
    if url.startswith("sqlite"):
        engine = create_engine(
            url, connect_args={"check_same_thread": False, "timeout": busy_timeout}
        )

        @event.listens_for(engine, "connect")
        def _pragmas(connection, _record) -> None:  # pragma: no cover - driver callback
            cursor = connection.cursor()
            cursor.execute("PRAGMA journal_mode=WAL")
            cursor.execute("PRAGMA synchronous=NORMAL")
            cursor.close()

        return engine
    return create_engine(url, pool_pre_ping=True, pool_timeout=busy_timeout)


class TaskStore:
    """Repository of tasks and uploads."""

    def __init__(self, engine: Engine) -> None:
        """A store on a database at the head revision (:func:`service.migrate.upgrade_database`)."""
        self.engine = engine
        self._sessions = sessionmaker(engine, expire_on_commit=False)

    @contextmanager
    def _session(self) -> Iterator[Session]:
        with self._sessions.begin() as session:
            yield session

    def create(self, request: dict[str, Any]) -> TaskRecord:
        row = TaskRow(
            id=uuid.uuid4().hex,
            status=TaskStatus.QUEUED.value,
            request=request,
            attempt=0,
            cancel_requested=False,
        )
        with self._session() as session:
            session.add(row)
        return TaskRecord.of(row)

    def get(self, task_id: str) -> TaskRecord | None:
        with self._session() as session:
            row = session.get(TaskRow, task_id)
            return TaskRecord.of(row) if row else None

    def list(
        self, status: TaskStatus | None = None, offset: int = 0, limit: int = 50
    ) -> tuple[list[TaskRecord], int]:
        """A page of tasks, newest first, and the total count matching the filter."""
        query = select(TaskRow)
        count = select(func.count()).select_from(TaskRow)
        if status is not None:
            query = query.where(TaskRow.status == status.value)
            count = count.where(TaskRow.status == status.value)
        query = query.order_by(TaskRow.created_at.desc(), TaskRow.id).offset(offset).limit(limit)
        with self._session() as session:
            rows = session.scalars(query).all()
            return [TaskRecord.of(r) for r in rows], int(session.scalar(count) or 0)

    def update(
        self, task_id: str, expect_attempt: int | None = None, **fields: Any
    ) -> TaskRecord | None:
        """Set columns of a task (``status`` may be a TaskStatus); returns the new record.

        A finished task keeps its status: a late progress report or a cancel racing a
        completion cannot reopen it. With ``expect_attempt``, nothing is written unless the task
        is still at that attempt (a job superseded by a restart writes nothing).
        """
        with self._session() as session:
            row = session.get(TaskRow, task_id, with_for_update=True)
            if row is None:
                return None
            if expect_attempt is not None and row.attempt != expect_attempt:
                return TaskRecord.of(row)
            if TaskStatus(row.status).finished and "status" in fields:
                return TaskRecord.of(row)
            for name, value in fields.items():
                setattr(row, name, value.value if isinstance(value, TaskStatus) else value)
            row.updated_at = _now()
            return TaskRecord.of(row)

    def finish(
        self,
        task_id: str,
        attempt: int,
        status: TaskStatus,
        result: dict[str, Any] | None,
        error: str | None,
    ) -> TaskRecord | None:
        """A job's last write: its outcome, unless the task moved on (another attempt, or
        already finished); a cancel asked for meanwhile wins over ``done``.

        One UPDATE statement, so a cancel cannot slip in between reading the flag and
        writing the status (a DELETE answered "cancel requested" must end ``cancelled``).
        """
        cancelled = (
            "cancelled while generating the missions"
            if status is TaskStatus.DONE
            else error or "cancelled"
        )
        active = [s.value for s in TaskStatus if not s.finished]
        statement = (
            update(TaskRow)
            .where(TaskRow.id == task_id, TaskRow.attempt == attempt)
            .where(TaskRow.status.in_(active))
            .values(
                status=case(
                    (TaskRow.cancel_requested, TaskStatus.CANCELLED.value), else_=status.value
                ),
                error=case((TaskRow.cancel_requested, cancelled), else_=error),
                result=result,
                updated_at=_now(),
            )
        )
        with self._session() as session:
            session.execute(statement)
        return self.get(task_id)

    def purge(self, finished_before: datetime, tasks_dir: Path) -> builtins.list[str]:
        """Delete finished tasks last changed before ``finished_before``, with their uploads
        and artifact directories; returns their ids."""
        finished = [s.value for s in TaskStatus if s.finished]
        query = select(TaskRow.id).where(
            TaskRow.status.in_(finished), TaskRow.updated_at < finished_before
        )
        with self._session() as session:
            ids = list(session.scalars(query).all())
            if ids:
                session.execute(delete(UploadRow).where(UploadRow.task_id.in_(ids)))
                session.execute(delete(TaskRow).where(TaskRow.id.in_(ids)))
        for task_id in ids:
            shutil.rmtree(tasks_dir / task_id, ignore_errors=True)
        return ids

    def unfinished(self) -> builtins.list[TaskRecord]:
        """Tasks queued or running, oldest first (what a restart must resume)."""
        active = [s.value for s in TaskStatus if not s.finished]
        query = select(TaskRow).where(TaskRow.status.in_(active)).order_by(TaskRow.created_at)
        with self._session() as session:
            return [TaskRecord.of(r) for r in session.scalars(query).all()]

    def counts_by_status(self) -> dict[str, int]:
        query = select(TaskRow.status, func.count()).group_by(TaskRow.status)
        with self._session() as session:
            counts = {status: count for status, count in session.execute(query).all()}
        return {s.value: int(counts.get(s.value, 0)) for s in TaskStatus}

    def add_upload(self, task_id: str, outcome: dict[str, Any]) -> None:
        with self._session() as session:
            session.add(UploadRow(task_id=task_id, outcome=outcome))

    def uploads(self, task_id: str) -> builtins.list[dict[str, Any]]:
        query = select(UploadRow).where(UploadRow.task_id == task_id).order_by(UploadRow.id)
        with self._session() as session:
            return [
                {"created_at": r.created_at.isoformat(), **r.outcome}
                for r in session.scalars(query).all()
            ]
