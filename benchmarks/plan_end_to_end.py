"""Wall-clock time of a whole ``flycrane plan`` of the Rescue task (issue 12, item 4).

    python benchmarks/plan_end_to_end.py [--runs 5] [--cold-runs 3] [--baseline DIR]

Each run is a new process, as a user's: imports, planning, the flight plan and its timing
tolerance, exports, MCAP log and plot. "cold" runs start from an empty numba cache each (a
fresh install's first run compiles the kernels), "warm" ones from the cache the first cold
run left. ``--baseline DIR`` times another checkout of the project (e.g. a ``git worktree``
of an older commit) with the same interpreter, alternating run by run so that both see the
same load, and prints the ratios of the medians.
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
    parser.add_argument("--cold-runs", type=int, default=3, help="cold runs per tree")
    parser.add_argument("--baseline", type=Path, help="another checkout to compare with")
    args = parser.parse_args(argv)
    if args.cold_runs < 1:
        parser.error("--cold-runs must be at least 1: the warm runs use the first one's cache")
    if args.runs < 1:
        parser.error("--runs must be at least 1: the warm runs' median is the figure")
    if args.baseline and not (args.baseline / "flycrane").is_dir():
        parser.error(f"--baseline {args.baseline}: not the root of a checkout of this project")
    trees = {"this": HERE} | ({"baseline": args.baseline.resolve()} if args.baseline else {})
    times: dict[str, dict[str, list[float]]] = {"cold": {}, "warm": {}}
    with tempfile.TemporaryDirectory(prefix="flycrane-plan-bench-") as scratch:
        root = Path(scratch)
        for kind, count in (("cold", args.cold_runs), ("warm", args.runs)):
            times[kind] = {name: [] for name in trees}
            for run in range(count):
                for name, tree in trees.items():
                    # each cold run compiles into a cache of its own; warm runs reuse the first
                    cache = root / f"numba-{name}-{run if kind == 'cold' else 0}"
                    times[kind][name].append(plan_once(tree, cache, root / name))
    medians = {
        kind: {name: statistics.median(t) for name, t in by_tree.items()}
        for kind, by_tree in times.items()
    }
    for name in trees:
        print(f"{name} ({trees[name]}):")
        for kind in ("cold", "warm"):
            each = " ".join(f"{t:.2f}" for t in times[kind][name])
            print(f"  {kind} median {medians[kind][name]:.2f} s (runs: {each})")
    if args.baseline:
        for kind in ("cold", "warm"):
            ratio = medians[kind]["baseline"] / medians[kind]["this"]
            print(f"{kind} speed-up against the baseline: {ratio:.2f}x")
    return 0


if __name__ == "__main__":
    sys.exit(main())
