"""What a server checks before it serves: that its data directory and its database work.

A server that starts on storage it cannot use fails later and worse: a task stuck for ever,
a traceback, every request answered "retry later". So the start is refused, with one line
naming the file and the reason (:class:`~service.errors.StartupError`), when

- the data directory cannot be written: a probe file of :data:`PROBE_BYTES` is written,
  synced and removed (a full disk, a read-only directory);
- the database does not open, or is corrupt: SQLite's ``PRAGMA quick_check`` (a file that
  is not a database, a malformed one, interior pages that nothing reads at start), before
  the schema is migrated;
- the database does not take a committed write (a read-only file or directory, a full
  disk, a PostgreSQL user without the right).

Both ``create_app``'s lifespan and ``flycrane serve`` (before uvicorn starts, so that the
user reads the line, not a traceback) call :func:`open_storage`.
"""

from __future__ import annotations

import os
import sqlite3
from pathlib import Path

from sqlalchemy import text
from sqlalchemy.engine import Engine
from sqlalchemy.exc import SQLAlchemyError

from service.errors import StartupError
from service.lifecycle import DataDirLock
from service.migrate import upgrade_database
from service.settings import Settings
from service.storage import database_reason, make_engine

#: Size of the probe file written at start: a disk with less free space fails the start.
PROBE_BYTES = 64 * 1024
PROBE_NAME = ".write-probe"
#: Problems of ``PRAGMA quick_check`` quoted in the refusal (it may list hundreds).
QUOTED_PROBLEMS = 3


def _one_line(text: str) -> str:
    return " ".join(text.split())


def check_data_dir(data_dir: Path) -> None:
    """Write, sync and remove a probe file of :data:`PROBE_BYTES` in ``data_dir``.

    Raises
    ------
    OSError
        If the directory cannot take it.
    """
    probe = data_dir / PROBE_NAME
    try:
        with probe.open("wb") as handle:
            handle.write(b"\0" * PROBE_BYTES)
            handle.flush()
            os.fsync(handle.fileno())
    finally:
        probe.unlink(missing_ok=True)


def check_database(engine: Engine) -> None:
    """Refuse a corrupt database, migrate it to the head revision, and commit a write.

    Raises
    ------
    StartupError
        Naming the database and what is wrong with it.
    """
    where = engine.url.render_as_string(hide_password=True)
    try:
        if engine.dialect.name == "sqlite":
            with engine.connect() as connection:
                found = [str(row[0]) for row in connection.execute(text("PRAGMA quick_check"))]
            if found != ["ok"]:
                quoted = "; ".join(found[:QUOTED_PROBLEMS])
                more = f" and {len(found) - QUOTED_PROBLEMS} more" if len(found) > 3 else ""
                raise StartupError(
                    _one_line(
                        f"cannot start: the database {where} is corrupt (PRAGMA quick_check: "
                        f"{quoted}{more}); restore it from a backup, or move it away to start "
                        "with an empty one"
                    )
                )
        upgrade_database(engine)
        with engine.begin() as connection:  # a write that must reach the disk
            connection.execute(text("UPDATE alembic_version SET version_num = version_num"))
    except (SQLAlchemyError, sqlite3.Error) as error:
        reason = database_reason(error) if isinstance(error, SQLAlchemyError) else str(error)
        corrupt = "malformed" in reason or "not a database" in reason
        if corrupt:
            advice = (
                "it is corrupt; restore it from a backup, or move it away to start with an "
                "empty one"
            )
        elif engine.dialect.name == "sqlite":
            advice = "check that it is writable and that its disk has space"
        else:  # a server: unreachable, refusing the login, or out of space
            advice = "check that its server runs and can be reached, the login, and its space"
        raise StartupError(
            _one_line(f"cannot start: the database {where} cannot be used: {reason} ({advice})")
        ) from None


def open_storage(settings: Settings) -> tuple[DataDirLock, Engine]:
    """Lock the data directory and open the database, both checked (module docstring); the
    caller releases the lock and disposes of the engine.

    Raises
    ------
    DataDirLockedError
        Another server holds the data directory.
    StartupError
        The data directory or the database cannot be used (one line).
    """
    data_dir = settings.data_dir
    lock: DataDirLock | None = None
    engine: Engine | None = None
    try:
        try:
            lock = DataDirLock(data_dir).acquire()
            check_data_dir(data_dir)
            settings.tasks_dir.mkdir(parents=True, exist_ok=True)
        except OSError as error:
            raise StartupError(
                _one_line(f"cannot start: the data directory {data_dir} cannot be written: {error}")
            ) from None
        engine = make_engine(settings.resolved_database_url, settings.database_busy_timeout)
        check_database(engine)
    except BaseException:
        if engine is not None:
            engine.dispose()
        if lock is not None:
            lock.release()
        raise
    return lock, engine
