"""What a server holds while it runs: the lock on its data directory, and the retention sweep.

One server per data directory: a second one would resume the first one's running tasks as
its own (both call them unfinished) and plan them twice. The lock is an ``flock`` on
``<data_dir>/server.lock``: the kernel releases it when the process ends, kill -9 included,
so a crashed server never blocks its successor. It covers servers on this machine; with
PostgreSQL shared between machines, give each server its own database.
"""

from __future__ import annotations

import fcntl
import logging
import os
from datetime import UTC, datetime, timedelta
from pathlib import Path
from typing import IO

from service.errors import DataDirLockedError
from service.storage import TaskStore

logger = logging.getLogger(__name__)

#: How often finished tasks past their retention are looked for [s].
RETENTION_INTERVAL = 3600.0


class DataDirLock:
    """An exclusive lock on a data directory, held until :meth:`release` or process exit."""

    def __init__(self, data_dir: Path) -> None:
        self.path = data_dir / "server.lock"
        self._file: IO[str] | None = None

    def acquire(self) -> DataDirLock:
        """Take the lock, or raise :class:`DataDirLockedError` naming the holder's pid."""
        self.path.parent.mkdir(parents=True, exist_ok=True)
        handle = self.path.open("a+", encoding="ascii")
        try:
            fcntl.flock(handle, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            handle.seek(0)
            holder = handle.read().strip() or "unknown"
            handle.close()
            raise DataDirLockedError(
                f"data directory {self.path.parent} is in use by another server (pid "
                f"{holder}); stop it or give this one another FLYCRANE_DATA_DIR"
            ) from None
        handle.seek(0)
        handle.truncate()
        handle.write(f"{os.getpid()}\n")
        handle.flush()
        self._file = handle
        return self

    def release(self) -> None:
        if self._file is not None:
            fcntl.flock(self._file, fcntl.LOCK_UN)
            self._file.close()
            self._file = None


def purge_expired(store: TaskStore, tasks_dir: Path, retention_days: float | None) -> list[str]:
    """Delete the tasks finished more than ``retention_days`` ago (None: keep all)."""
    if retention_days is None:
        return []
    cutoff = datetime.now(UTC) - timedelta(days=retention_days)
    purged = store.purge(cutoff, tasks_dir)
    if purged:
        logger.info("deleted %d tasks finished before %s", len(purged), cutoff.isoformat())
    return purged
