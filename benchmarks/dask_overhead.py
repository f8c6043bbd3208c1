"""The benchmark's seeds on the local process pool against a Dask cluster of the same size.

    python benchmarks/dask_overhead.py [--runs 100] [--workers 2] [--rounds 2]

Runs ``--runs`` seeds of T-RRT on the Rescue (``flycrane bench``'s jobs, through
:func:`flycrane.analysis.benchmark.run_benchmark`) on a local pool of ``--workers`` processes and on
a Dask ``LocalCluster`` of as many single-threaded worker processes on loopback, alternately,
``--rounds`` times each, in one process; prints the wall time of each and the ratio of the medians
(Dask / local), and checks that both gave the same result for every seed.
"""

from __future__ import annotations

import argparse
import logging
import statistics
import time

from bench_input import at_least_one
from distributed import LocalCluster

from flycrane.analysis.benchmark import run_benchmark
from flycrane.execution import DaskExecutor, local_executor


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=at_least_one, default=100, help="seeds")
    parser.add_argument("--workers", type=int, default=2, help="processes on either side")
    parser.add_argument("--rounds", type=int, default=2)
    args = parser.parse_args()
    cluster = LocalCluster(
        n_workers=args.workers,
        threads_per_worker=1,
        processes=True,
        host="127.0.0.1",
        dashboard_address=None,
        silence_logs=logging.ERROR,
    )
    seconds: dict[str, list[float]] = {"local": [], "dask": []}
    results: dict[str, dict] = {}
    try:
        for _ in range(args.rounds):
            for name in ("local", "dask"):
                executor = (
                    local_executor(args.workers)
                    if name == "local"
                    else DaskExecutor(cluster.scheduler_address)
                )
                clock = time.perf_counter()
                with executor:
                    records = list(run_benchmark(executor, ["rescue"], ["trrt"], args.runs, 60.0))
                seconds[name].append(time.perf_counter() - clock)
                results[name] = {r.seed: (r.status, r.nodes, r.path) for r in records}
                solved = sum(r.status == "exact_solution" for r in records)
                print(
                    f"{name:5s}: {args.runs} seeds in {seconds[name][-1]:6.2f} s ({solved} solved)"
                )
    finally:
        cluster.close()
    same = results["local"] == results["dask"]
    ratio = statistics.median(seconds["dask"]) / statistics.median(seconds["local"])
    print(f"same result for every seed: {same}; Dask / local wall time (medians): {ratio:.2f}")


if __name__ == "__main__":
    main()
