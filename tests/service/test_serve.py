"""``flycrane serve`` as a user runs it: a real uvicorn process on a loopback address.

Issue 22, item 13: on ``--host ::1`` every request was answered 400 "Invalid host header"
(the default allowed hosts hold ``::1``, Starlette compares ``[::1]``).
"""

from __future__ import annotations

import os
import signal
import socket
import subprocess
import sys
import time
from collections.abc import Iterator
from contextlib import contextmanager, suppress
from pathlib import Path

import httpx
import pytest

ROOT = Path(__file__).resolve().parents[2]
#: Generous for a loaded 2-core machine: the server imports the service (seconds).
START_WITHIN = 90.0


def serve_command(data_dir: Path, *args: str) -> list[str]:
    return [sys.executable, "-m", "flycrane.cli", "serve", "--data-dir", str(data_dir), *args]


def clean_environment() -> dict[str, str]:
    return {k: v for k, v in os.environ.items() if not k.startswith("FLYCRANE_")}


def free_port(family: socket.AddressFamily, host: str) -> int:
    with socket.socket(family, socket.SOCK_STREAM) as s:
        s.bind((host, 0))
        return s.getsockname()[1]


def ipv6_loopback() -> bool:
    try:
        free_port(socket.AF_INET6, "::1")
    except OSError:
        return False
    return True


@contextmanager
def served(data_dir: Path, host: str, port: int) -> Iterator[httpx.Client]:
    """``flycrane serve`` on ``host``: a client once it answers HTTP at all (whatever the
    status); stopped by its session's id at the end, pass or fail."""
    log = data_dir.parent / f"{data_dir.name}.log"
    with log.open("wb") as out:
        process = subprocess.Popen(
            serve_command(data_dir, "--host", host, "--port", str(port), "--workers", "1"),
            cwd=ROOT,
            env=clean_environment(),
            stdout=out,
            stderr=subprocess.STDOUT,
            start_new_session=True,
        )
    netloc = f"[{host}]" if ":" in host else host
    client = httpx.Client(base_url=f"http://{netloc}:{port}/", timeout=30.0)
    try:
        deadline = time.monotonic() + START_WITHIN
        while True:
            assert process.poll() is None, log.read_text(errors="replace")
            try:
                client.get("/healthz")
                break
            except httpx.TransportError:
                assert time.monotonic() < deadline, log.read_text(errors="replace")
                time.sleep(0.2)
        yield client
    finally:
        client.close()
        with suppress(ProcessLookupError):
            os.killpg(process.pid, signal.SIGTERM)
        try:
            process.wait(timeout=30)
        except subprocess.TimeoutExpired:
            os.killpg(process.pid, signal.SIGKILL)
            process.wait()


def test_serve_on_the_ipv6_loopback_answers(tmp_path):
    if not ipv6_loopback():
        pytest.skip("IPv6 loopback unavailable here: ::1 cannot be bound")
    with served(tmp_path / "data", "::1", free_port(socket.AF_INET6, "::1")) as client:
        health = client.get("/healthz")
        assert health.status_code == 200, health.text
        assert client.get("/v1/tasks").status_code == 200
        # other names are still refused
        assert client.get("/healthz", headers={"host": "evil.example"}).status_code == 400


@pytest.mark.parametrize(("port", "why"), [("99999", "99999 is outside 1-65535"),
                                           ("0", "0 is outside 1-65535"),
                                           ("http", "not a whole number: 'http'")])  # fmt: skip
def test_a_port_no_socket_can_take_is_refused_with_its_name(port, why, tmp_path):
    """Before, uvicorn's bind() raised OverflowError with a traceback (exit 1)."""
    done = subprocess.run(
        serve_command(tmp_path / "data", "--port", port),
        capture_output=True, text=True, timeout=60, env=clean_environment(),
    )  # fmt: skip
    assert done.returncode == 2
    assert f"argument --port: {why}" in done.stderr and "Traceback" not in done.stderr
    assert not (tmp_path / "data").exists()
