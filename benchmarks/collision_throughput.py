"""Collision-checker throughput on the benchmark scenes.

    python benchmarks/collision_throughput.py [--count 4000]

Configurations uniform in each scene's sampling bounds (so some touch obstacles and most
do not, as the planner sees them); prints configurations per second for batches (motion
checks check ~20-60 at once) and single calls (state checks).
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from flycrane.planning.problem import PlanningProblem


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--count", type=int, default=4000)
    args = parser.parse_args()
    for name in ("rescue", "puzzle"):
        problem = PlanningProblem.named(name)
        checker = problem.validity.collision
        q = problem.space.sample_uniform(np.random.default_rng(0), args.count)
        checker.collision_free(q[:10])
        for batch in (1, 32):
            clock = time.perf_counter()
            free = [checker.collision_free(q[i : i + batch]) for i in range(0, len(q), batch)]
            seconds = time.perf_counter() - clock
            print(
                f"{name:7s} batch {batch:3d}: {len(q) / seconds:9,.0f} configurations/s "
                f"({1e6 * seconds / len(q):6.1f} us each), "
                f"{np.concatenate(free).mean():.0%} collision-free"
            )


if __name__ == "__main__":
    main()
