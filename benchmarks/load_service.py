"""Load test of the HTTP service on loopback: concurrent submissions and API latency.

    python benchmarks/load_service.py [--tasks 50] [--clients 10] [--poll-seconds 20]

Starts ``flycrane serve`` on a free loopback port with a fresh data directory, submits
``--tasks`` Rescue tasks from ``--clients`` concurrent clients, then measures the latency of
``GET /v1/tasks/{id}`` from 4 pollers while the workers plan, and finally cancels what is
left. It prints how many submissions were accepted (202) or refused (429/503), checks that
every accepted task is listed (none lost), and the latency percentiles. Bounded: at most a
few minutes; everything stays on 127.0.0.1.
"""

from __future__ import annotations

import argparse
import os
import random
import socket
import subprocess
import sys
import tempfile
import threading
import time
from concurrent.futures import ThreadPoolExecutor

import httpx
import numpy as np


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--tasks", type=int, default=50)
    parser.add_argument("--clients", type=int, default=10)
    parser.add_argument("--poll-seconds", type=float, default=20.0)
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--queue", type=int, default=32, help="FLYCRANE_MAX_QUEUED_TASKS")
    args = parser.parse_args()

    port = free_port()
    data = tempfile.mkdtemp(prefix="flycrane-load-")
    env = {**os.environ, "FLYCRANE_MAX_QUEUED_TASKS": str(args.queue)}
    server = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "flycrane.cli",
            "serve",
            "--port",
            str(port),
            "--data-dir",
            data,
            "--workers",
            str(args.workers),
        ],
        env=env,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    base = f"http://127.0.0.1:{port}"
    try:
        for _ in range(100):
            try:
                if httpx.get(f"{base}/healthz", timeout=1).status_code == 200:
                    break
            except httpx.HTTPError:
                time.sleep(0.2)
        else:
            raise RuntimeError("the service did not start")

        def submit(n: int) -> tuple[int, str | None]:
            body = {"name": f"load {n}", "planner": {"seed": n, "time_budget": 30}}
            response = httpx.post(f"{base}/v1/tasks", json=body, timeout=60)
            return response.status_code, response.json().get("id")

        clock = time.perf_counter()
        with ThreadPoolExecutor(args.clients) as pool:
            outcomes = list(pool.map(submit, range(args.tasks)))
        submit_seconds = time.perf_counter() - clock
        codes = [code for code, _ in outcomes]
        accepted = [task_id for code, task_id in outcomes if code == 202]
        refused = sum(code in (429, 503) for code in codes)
        other = [code for code in codes if code not in (202, 429, 503)]

        latencies: list[float] = []
        lock = threading.Lock()
        stop = time.monotonic() + args.poll_seconds

        def poll() -> None:
            with httpx.Client(base_url=base, timeout=10) as client:
                while time.monotonic() < stop:
                    start = time.perf_counter()
                    client.get(f"/v1/tasks/{random.choice(accepted)}").raise_for_status()
                    with lock:
                        latencies.append(time.perf_counter() - start)

        planning = httpx.get(f"{base}/v1/tasks", params={"status": "planning"}).json()["total"]
        threads = [threading.Thread(target=poll) for _ in range(4)]
        for thread in threads:
            thread.start()
        for thread in threads:
            thread.join()
        listed = {
            t["id"] for t in httpx.get(f"{base}/v1/tasks", params={"limit": 500}).json()["items"]
        }
        for task_id in accepted:
            httpx.delete(f"{base}/v1/tasks/{task_id}", timeout=30)
        done = httpx.get(f"{base}/v1/tasks", params={"status": "done"}).json()["total"]
        lost = [task_id for task_id in accepted if task_id not in listed]
        ms = 1000 * np.array(latencies)
        print(
            f"submissions: {args.tasks} from {args.clients} clients in {submit_seconds:.2f} s: "
            f"{len(accepted)} accepted (202), {refused} refused (429/503), other {other}"
        )
        print(f"lost: {len(lost)} of {len(accepted)} accepted tasks missing from the listing")
        print(
            f"GET /v1/tasks/{{id}} while {args.workers} workers plan ({planning} planning at "
            f"start): {len(ms)} requests, p50 {np.percentile(ms, 50):.1f} ms, "
            f"p95 {np.percentile(ms, 95):.1f} ms, max {ms.max():.1f} ms"
        )
        print(f"tasks done before the cancel: {done}")
        return 0 if not lost and not other else 1
    finally:
        server.terminate()
        server.wait(timeout=30)


if __name__ == "__main__":
    sys.exit(main())
