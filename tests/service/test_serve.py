"""``flycrane serve`` as a user runs it: a real uvicorn process on a loopback address.

Issue 22, item 13: on ``--host ::1`` every request was answered 400 "Invalid host header"
(the default allowed hosts hold ``::1``, Starlette compares ``[::1]``). Behind the README's
proxy setup, the Docker image's health check got that answer too. Settings the server cannot
work with are refused at start, in one line naming the setting.
"""

from __future__ import annotations

import json
import os
import re
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
def served(
    data_dir: Path, host: str, port: int, *args: str, env: dict[str, str] | None = None
) -> Iterator[httpx.Client]:
    """``flycrane serve`` on ``host`` (more arguments and ``FLYCRANE_*`` variables in
    ``args`` and ``env``): a client once it answers HTTP at all (whatever the status);
    stopped by its session's id at the end, pass or fail."""
    log = data_dir.parent / f"{data_dir.name}.log"
    command = serve_command(data_dir, "--host", host, "--port", str(port), "--workers", "1")
    with log.open("wb") as out:
        process = subprocess.Popen(
            [*command, *args],
            cwd=ROOT,
            env={**clean_environment(), **(env or {})},
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


def dockerfile_health_check(port: int) -> list[str]:
    """The Dockerfile's HEALTHCHECK command, on ``port`` instead of the image's 8000, run by
    this interpreter."""
    text = (ROOT / "docker" / "Dockerfile").read_text(encoding="utf-8")
    found = re.search(r"^HEALTHCHECK .*\\\n\s*CMD (\[.*\])$", text, re.MULTILINE)
    assert found, "no HEALTHCHECK ... CMD [...] in docker/Dockerfile"
    command = json.loads(found.group(1))
    assert command[0] == "python" and "http://127.0.0.1:8000/healthz" in command[-1], command
    return [sys.executable, *(part.replace(":8000/", f":{port}/") for part in command[1:])]


def test_the_docker_health_check_passes_behind_the_readmes_proxy_setup(tmp_path):
    """README "Security": ALLOWED_HOSTS names the public host, ``--proxy-headers``; the image's
    health check asks http://127.0.0.1:8000/healthz and got 400, so the container was never
    healthy. Other routes still answer only the public name."""
    port = free_port(socket.AF_INET, "127.0.0.1")
    proxied = {"FLYCRANE_ALLOWED_HOSTS": '["crane.example.org"]'}
    with served(tmp_path / "data", "127.0.0.1", port, "--proxy-headers", env=proxied) as client:
        check = subprocess.run(
            dockerfile_health_check(port), capture_output=True, text=True, timeout=60
        )
        assert check.returncode == 0, check.stderr[-3000:]
        assert client.get("/v1/tasks").status_code == 400  # addressed to 127.0.0.1
        public = {"host": "crane.example.org"}
        assert client.get("/v1/tasks", headers=public).status_code == 200
        assert client.get("/healthz", headers={"host": "evil.example"}).status_code == 400


@pytest.mark.parametrize(
    ("variable", "value", "why"),
    [
        ("FLYCRANE_UPLOAD_DEVICES", '["/dev/ttyUSB[0-9]+", "["]',
         "'[' is not a regular expression: unterminated character set"),
        ("FLYCRANE_DATABASE_URL", "bogus://", "sqlalchemy.dialects:bogus"),
        ("FLYCRANE_DATABASE_URL", "not a url", "Could not parse SQLAlchemy URL"),
        ("FLYCRANE_DATABASE_URL", "postgresql://h:port/db", "not a database URL"),
        ("FLYCRANE_ALLOWED_HOSTS", "localhost", "not JSON: a list is written as JSON"),
        ("FLYCRANE_RETENTION_DAYS", "forever", "valid number"),
    ],
)  # fmt: skip
def test_a_setting_the_server_cannot_use_is_refused_in_one_line(tmp_path, variable, value, why):
    """Before, a broken UPLOAD_DEVICES pattern started, then every upload was a 500
    (re.error); a DATABASE_URL SQLAlchemy cannot load ended the start in a traceback."""
    done = subprocess.run(
        serve_command(tmp_path / "data"),
        capture_output=True, text=True, timeout=120,
        env={**clean_environment(), variable: value},
    )  # fmt: skip
    assert done.returncode == 2, done.stderr[-3000:]
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(f"flycrane serve: {variable}: "), lines
    assert why in lines[0] and "Traceback" not in done.stderr
    assert not (tmp_path / "data").exists()


def test_a_scheduler_that_does_not_answer_is_refused_in_one_line(tmp_path):
    """The start ended in some hundred lines of uvicorn's and Dask's traceback."""
    environment = {**clean_environment(), "FLYCRANE_EXECUTOR": "dask://127.0.0.1:9",
                   "DASK_DISTRIBUTED__COMM__TIMEOUTS__CONNECT": "2s"}  # fmt: skip
    done = subprocess.run(
        serve_command(tmp_path / "data"), capture_output=True, text=True, timeout=120,
        env=environment,
    )  # fmt: skip
    assert done.returncode == 1, done.stderr[-3000:]
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in done.stderr
    assert lines[0].startswith("flycrane serve: FLYCRANE_EXECUTOR: no Dask scheduler answers")
