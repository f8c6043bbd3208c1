"""Wall-clock time of a whole ``flycrane plan`` of the Rescue task (issue 12, item 4).

    python benchmarks/plan_end_to_end.py [--runs 5] [--baseline DIR]

Each run is a new process, as a user's: imports, planning, the flight plan and its timing
tolerance, exports, MCAP log and plot. "cold" runs with an empty numba cache (a fresh
install's first run compiles the kernels), "warm" with the cache the first run left.
``--baseline DIR`` times another checkout of the project (e.g. a ``git worktree`` of an older
commit) with the same interpreter, alternating run by run so that both see the same load,
and prints the ratio of the medians.
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parents[1]


def plan_once(tree: Path, numba_cache: Path, out: Path) -> float:
    env = dict(os.environ, PYTHONPATH=str(tree), NUMBA_CACHE_DIR=str(numba_cache))
    command = [sys.executable, "-m", "flycrane.cli", "plan", "--out", str(out)]
    start = time.perf_counter()
    subprocess.run(command, env=env, cwd=tree, check=True, capture_output=True, timeout=600)
    return time.perf_counter() - start


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=5, help="warm runs per tree")
    parser.add_argument("--baseline", type=Path, help="another checkout to compare with")
    args = parser.parse_args(argv)
    trees = {"this": HERE} | ({"baseline": args.baseline.resolve()} if args.baseline else {})
    with tempfile.TemporaryDirectory(prefix="flycrane-plan-bench-") as scratch:
        root = Path(scratch)
        caches = {name: root / f"numba-{name}" for name in trees}
        cold = {name: plan_once(tree, caches[name], root / name) for name, tree in trees.items()}
        warm: dict[str, list[float]] = {name: [] for name in trees}
        for _ in range(args.runs):
            for name, tree in trees.items():
                warm[name].append(plan_once(tree, caches[name], root / name))
    for name in trees:
        runs = " ".join(f"{t:.2f}" for t in warm[name])
        print(
            f"{name} ({trees[name]}): cold {cold[name]:.2f} s; warm median "
            f"{statistics.median(warm[name]):.2f} s (runs: {runs})"
        )
    if args.baseline:
        ratio = statistics.median(warm["baseline"]) / statistics.median(warm["this"])
        print(f"warm speed-up against the baseline: {ratio:.2f}x")
    return 0


if __name__ == "__main__":
    sys.exit(main())
