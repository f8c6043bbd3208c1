"""A private PostgreSQL server for one test session: Debian's binaries (``make postgres``),
a cluster in a temporary directory, reachable only through a Unix socket in that directory
(no TCP port at all), stopped by its PID when the session ends, pass or fail.

PostgreSQL refuses to run as root, so as root the server runs as the ``postgres`` user the
Debian package creates. Each test asks for a database of its own (:meth:`new_database`).
"""

from __future__ import annotations

import glob
import itertools
import os
import pwd
import shutil
import signal
import subprocess
import tempfile
import time
from pathlib import Path

import psycopg

#: Durability is not under test: no fsync makes a cluster start and commit faster.
FAST = ("-c", "fsync=off", "-c", "synchronous_commit=off", "-c", "full_page_writes=off")
START_TIMEOUT_S = 60.0
PORT = 5432  #: names the socket file only; nothing listens on TCP


class PostgresUnavailable(RuntimeError):
    """Why no server could be started (the tests that need one skip with it)."""


def _binaries() -> Path:
    found = sorted(
        glob.glob("/usr/lib/postgresql/*/bin/initdb"), key=lambda p: int(p.split("/")[4])
    )
    if found:
        return Path(found[-1]).parent
    initdb = shutil.which("initdb")
    if initdb:
        return Path(initdb).parent
    raise PostgresUnavailable(
        "no PostgreSQL server binaries (initdb); `make postgres` installs them"
    )


class PostgresServer:
    """A running private cluster (module docstring)."""

    def __init__(self) -> None:
        binaries = _binaries()
        self.user = "postgres" if os.geteuid() == 0 else None
        self.root = Path(tempfile.mkdtemp(prefix="flycrane-postgres-"))
        if self.user:
            entry = pwd.getpwnam(self.user)
            os.chown(self.root, entry.pw_uid, entry.pw_gid)
        data = self.root / "data"
        self._names = itertools.count()
        initdb = [str(binaries / "initdb"), "-D", str(data), "-U", "flycrane", "--auth=trust",
                  "--no-sync", "-E", "UTF8", "--locale=C"]  # fmt: skip
        done = subprocess.run(initdb, user=self.user, capture_output=True, text=True, timeout=120)
        if done.returncode != 0:
            shutil.rmtree(self.root, ignore_errors=True)
            raise PostgresUnavailable(f"initdb failed: {done.stderr.strip()[-500:]}")
        self.log = (self.root / "server.log").open("wb")
        command = [str(binaries / "postgres"), "-D", str(data), "-k", str(self.root),
                   "-p", str(PORT), "-c", "listen_addresses=", *FAST]  # fmt: skip
        self.process = subprocess.Popen(
            command, user=self.user, stdout=self.log, stderr=subprocess.STDOUT,
            start_new_session=True,
        )  # fmt: skip
        try:
            self._wait_ready()
        except PostgresUnavailable:
            self.stop()
            raise

    def _connect(self, database: str = "postgres") -> psycopg.Connection:
        return psycopg.connect(
            host=str(self.root), port=PORT, user="flycrane", dbname=database, autocommit=True
        )

    def _wait_ready(self) -> None:
        deadline = time.monotonic() + START_TIMEOUT_S
        while time.monotonic() < deadline:
            if self.process.poll() is not None:
                log = (self.root / "server.log").read_text(errors="replace")
                raise PostgresUnavailable(f"the server exited at start: {log[-500:]}")
            try:
                self._connect().close()
                return
            except psycopg.OperationalError:
                time.sleep(0.1)
        raise PostgresUnavailable(f"the server did not accept connections in {START_TIMEOUT_S} s")

    def new_database(self) -> str:
        """A new empty database; its SQLAlchemy URL."""
        name = f"test_{os.getpid()}_{next(self._names)}"
        with self._connect() as connection:
            connection.execute(f'CREATE DATABASE "{name}"')
        return f"postgresql+psycopg://flycrane@/{name}?host={self.root}&port={PORT}"

    def stop(self) -> None:
        """Fast shutdown by PID (SIGINT), SIGKILL if it does not end; remove the cluster."""
        if self.process.poll() is None:
            self.process.send_signal(signal.SIGINT)
            try:
                self.process.wait(timeout=30)
            except subprocess.TimeoutExpired:
                os.killpg(self.process.pid, signal.SIGKILL)
                self.process.wait()
        self.log.close()
        shutil.rmtree(self.root, ignore_errors=True)
