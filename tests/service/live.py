"""The service as a person reaches it: uvicorn in its own process on a loopback port, and
Debian's Chromium driven by Playwright (never Playwright's own browser download)."""

from __future__ import annotations

import os
import signal
import socket
import subprocess
import sys
import time
from collections.abc import Iterator
from contextlib import contextmanager, suppress
from dataclasses import dataclass
from pathlib import Path

import httpx

from tests.service.conftest import wait_finished

CHROMIUM = Path("/usr/bin/chromium")
#: Headless, no GPU (software WebGL), nothing fetched by the browser on its own.
CHROMIUM_ARGS = [
    "--headless",
    "--no-sandbox",
    "--disable-gpu",
    "--disable-quic",
    "--no-first-run",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
]
ROOT = Path(__file__).resolve().parents[2]


@dataclass
class Server:
    """A service process started by :func:`start_server`: its process and a client."""

    process: subprocess.Popen
    client: httpx.Client
    log: Path

    @property
    def pid(self) -> int:
        return self.process.pid

    def stop(self, sig: int = signal.SIGTERM, timeout: float = 20.0) -> None:
        """Send ``sig`` to the server's session (the server and everything it started) and
        wait; SIGKILL if it has not exited within ``timeout``."""
        self.client.close()
        with suppress(ProcessLookupError):
            os.killpg(self.pid, sig)
        try:
            self.process.wait(timeout=timeout)
        except subprocess.TimeoutExpired:
            os.killpg(self.pid, signal.SIGKILL)
            self.process.wait()


def start_server(data_dir: Path, timeout: float = 60.0, workers: int = 1) -> Server:
    """The service (``service.app:create_app``) serving ``data_dir`` over HTTP on loopback.

    The port is the kernel's choice: the socket is bound here and handed to uvicorn (--fd),
    so nothing else can take it in between. The server and its worker processes run in a
    session of their own, whose id is the server's PID.
    """
    listener = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
    listener.bind(("127.0.0.1", 0))
    listener.listen(64)
    port = listener.getsockname()[1]
    env = {k: v for k, v in os.environ.items() if not k.startswith("FLYCRANE_")}
    env.update(FLYCRANE_DATA_DIR=str(data_dir), FLYCRANE_WORKERS=str(workers))
    log_path = data_dir / "uvicorn.log"
    with log_path.open("ab") as log:
        process = subprocess.Popen(
            [sys.executable, "-m", "uvicorn", "--factory", "service.app:create_app"]
            + ["--fd", str(listener.fileno()), "--log-level", "warning"],
            pass_fds=(listener.fileno(),),
            env=env,
            cwd=ROOT,
            stdout=log,
            stderr=subprocess.STDOUT,
            start_new_session=True,
        )
    listener.close()
    server = Server(
        process, httpx.Client(base_url=f"http://127.0.0.1:{port}/", timeout=30.0), log_path
    )
    deadline = time.monotonic() + timeout
    while True:
        if process.poll() is not None:
            server.stop()
            raise AssertionError(f"uvicorn exited: {log_path.read_text(errors='replace')}")
        try:
            if server.client.get("/healthz").status_code == 200:
                return server
        except httpx.TransportError:
            pass
        if time.monotonic() > deadline:
            server.stop(signal.SIGKILL)
            raise AssertionError(f"service not up in {timeout} s: {log_path.read_text()}")
        time.sleep(0.2)


@contextmanager
def live_service(data_dir: Path, timeout: float = 60.0) -> Iterator[tuple[httpx.Client, Path]]:
    """:func:`start_server` with one worker, stopped at the end, pass or fail."""
    server = start_server(data_dir, timeout)
    try:
        yield server.client, data_dir
    finally:
        server.stop()


def planned_task(client: httpx.Client, body: dict, timeout: float = 120.0) -> dict:
    """Submit a task and wait until it is finished; returns it (status done asserted)."""
    accepted = client.post("/v1/tasks", json=body)
    assert accepted.status_code == 202, accepted.text
    task = wait_finished(client, accepted.json()["id"], timeout)
    assert task["status"] == "done", task["error"]
    return task


@contextmanager
def browser_context(profile: Path) -> Iterator:
    """A Chromium context with a fresh profile in ``profile``, a 1280 x 800 window."""
    from playwright.sync_api import sync_playwright

    with sync_playwright() as playwright:
        context = playwright.chromium.launch_persistent_context(
            str(profile),
            executable_path=str(CHROMIUM),
            headless=True,
            args=CHROMIUM_ARGS,
            viewport={"width": 1280, "height": 800},
            timeout=60_000,
        )
        try:
            yield context
        finally:
            context.close()
