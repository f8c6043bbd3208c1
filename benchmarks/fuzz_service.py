"""Fuzz the HTTP service against its own OpenAPI description with schemathesis.

    python benchmarks/fuzz_service.py [--max-examples 200] [--max-time 1200] [--seed 1]

Starts ``flycrane serve`` on a free loopback port with a fresh data directory (one worker,
a queue large enough that no valid task is refused with 503), runs ``schemathesis run``
on ``/openapi.json`` with every phase (examples, coverage, fuzzing, stateful) and the checks
"no server error" and "status code, content type, headers and body as documented", then
prints the run's figures and what the server saw. Exits 0 only if schemathesis found no
failure and the server still answers /healthz with 200. Bounded by ``--max-time`` plus a
minute; the server is stopped by its PID (its whole session) at the end, pass or fail.

The test suite runs it small (tests/service/test_fuzz.py); the long run's figures are in
BENCHMARKS.md.
"""

from __future__ import annotations

import argparse
import json
import os
import signal
import socket
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import httpx

CHECKS = (
    "not_a_server_error",
    "status_code_conformance",
    "content_type_conformance",
    "response_headers_conformance",
    "response_schema_conformance",
)


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def start_server(data: Path, port: int) -> subprocess.Popen:
    env = {k: v for k, v in os.environ.items() if not k.startswith("FLYCRANE_")}
    env.update(FLYCRANE_MAX_QUEUED_TASKS="1000000", FLYCRANE_WORKERS="1")
    log = (data / "server.log").open("wb")
    command = [sys.executable, "-m", "flycrane.cli", "serve", "--port", str(port)]
    return subprocess.Popen(
        [*command, "--data-dir", str(data)],
        env=env,
        stdout=log,
        stderr=subprocess.STDOUT,
        start_new_session=True,
    )


def wait_healthy(base: str, server: subprocess.Popen, timeout: float = 60.0) -> None:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if server.poll() is not None:
            raise RuntimeError("the service exited at start")
        try:
            if httpx.get(f"{base}/healthz", timeout=2).status_code == 200:
                return
        except httpx.HTTPError:
            pass
        time.sleep(0.2)
    raise RuntimeError("the service did not start")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--max-examples", type=int, default=200, help="per operation and phase")
    parser.add_argument("--max-time", type=int, default=1200, help="whole run [s]")
    parser.add_argument("--seed", type=int, default=1)
    args = parser.parse_args(argv)

    data = Path(tempfile.mkdtemp(prefix="flycrane-fuzz-"))
    port = free_port()
    base = f"http://127.0.0.1:{port}"
    server = start_server(data, port)
    try:
        wait_healthy(base, server)
        report = data / "schemathesis.json"
        command = [
            str(Path(sys.executable).with_name("schemathesis")),
            "run",
            f"{base}/openapi.json",
            "--checks",
            ",".join(CHECKS),
            "--max-examples",
            str(args.max_examples),
            "--max-time",
            str(args.max_time),
            "--seed",
            str(args.seed),
            "--workers",
            "1",
            "--request-timeout",
            "60",
            "--report",
            "json",
            "--report-json-path",
            str(report),
        ]
        clock = time.perf_counter()
        run = subprocess.run(
            command,
            cwd=data,
            capture_output=True,
            text=True,
            timeout=args.max_time + 60,
            check=False,
        )
        seconds = time.perf_counter() - clock
        if not report.exists():
            print(run.stdout[-5000:], run.stderr[-5000:])
            return 2
        result = json.loads(report.read_text())
        health = httpx.get(f"{base}/healthz", timeout=10)
        tasks = httpx.get(f"{base}/v1/tasks", params={"limit": 1}, timeout=10).json()["total"]
        submissions = {
            line.split('outcome="')[1].split('"')[0]: float(line.rsplit(" ", 1)[1])
            for line in httpx.get(f"{base}/metrics", timeout=10).text.splitlines()
            if line.startswith("flycrane_task_submissions_total{")
        }
        cases = result["test_cases"]
        print(
            f"schemathesis {result['schemathesis_version']}, seed {result['seed']}, "
            f"--max-examples {args.max_examples}: {cases['generated']} test cases on "
            f"{result['operations']['tested']} operations in {seconds:.0f} s "
            f"(stopped by: {result['stop_reason']})"
        )
        failures = result["failures"]
        print(f"failures: {len(failures)} kinds, {cases['with_failures']} failing test cases")
        for failure in failures:
            print(f"  {failure['code']} {failure['title']}: {failure['count']} in "
                  f"{', '.join(failure['operations'])}")  # fmt: skip
        print(
            f"server: /healthz {health.status_code} after the run; {tasks} tasks stored; "
            f"POST /v1/tasks outcomes {json.dumps(submissions, sort_keys=True)}"
        )
        if failures or health.status_code != 200:
            print(run.stdout[-20_000:])
            return 1
        return 0
    finally:
        stop_server(server)


def stop_server(server: subprocess.Popen) -> None:
    """Stop the server's session (server and workers) by its PID: TERM, then KILL."""
    try:
        os.killpg(server.pid, signal.SIGTERM)
        server.wait(timeout=30)
    except subprocess.TimeoutExpired:
        os.killpg(server.pid, signal.SIGKILL)
        server.wait()
    except ProcessLookupError:
        pass


if __name__ == "__main__":
    sys.exit(main())
