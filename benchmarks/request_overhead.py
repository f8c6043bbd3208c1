"""Cost of one API request in-process, without a network or a load: the request path alone.

    python benchmarks/request_overhead.py [--requests 2000]

Builds the application on a fresh data directory (starlette's TestClient, lifespan
running), stores one task and times ``GET /v1/tasks/{id}`` sequentially after 200
warm-up requests; prints the median and 95th percentile. Compares code versions run on
the same machine one after the other (BENCHMARKS.md, "Service under load").
"""

from __future__ import annotations

import argparse
import tempfile
import time

import numpy as np
from fastapi.testclient import TestClient

from service.app import create_app
from service.settings import Settings


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--requests", type=int, default=2000)
    args = parser.parse_args()
    settings = Settings(data_dir=tempfile.mkdtemp(prefix="flycrane-req-"), workers=1)
    settings = settings.model_copy(update={"allowed_hosts": ("testserver",)})
    app = create_app(settings)
    with TestClient(app) as client:
        task = app.state.service.store.create({"name": "timed"})
        for _ in range(200):
            client.get(f"/v1/tasks/{task.id}")
        seconds = []
        for _ in range(args.requests):
            start = time.perf_counter()
            client.get(f"/v1/tasks/{task.id}").raise_for_status()
            seconds.append(time.perf_counter() - start)
    ms = 1000 * np.array(seconds)
    print(
        f"GET /v1/tasks/{{id}} in-process, {args.requests} sequential requests: "
        f"median {np.median(ms):.2f} ms, p95 {np.percentile(ms, 95):.2f} ms"
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
