"""Cost evaluations per second on the default system, compiled kernel vs numpy reference.

    python benchmarks/cost_throughput.py [--seconds 1.0]

Batches of 1, 64 and 4096 configurations drawn around the hover pose (about half of them
feasible, so both the finite and the +inf branches run). Each figure is the best of five
timed rounds of at least ``--seconds / 5`` each; both paths run in this one process, and the
ratio compiled/numpy is printed per batch size.
"""

from __future__ import annotations

import argparse
import platform
import time

import numpy as np

from flycrane.model.cable_system import CableSystem
from flycrane.model.cost import cost_from_report
from flycrane.model.statics import evaluate_statics
from flycrane.model.statics_kernel import configuration_cost


def sample(n: int, rng: np.random.Generator) -> np.ndarray:
    q = np.empty((n, 9))
    q[:, :3] = rng.uniform([-10, -10, 2], [10, 10, 20], (n, 3))
    q[:, 3] = rng.uniform(-np.pi, np.pi, n)
    q[:, 4] = rng.uniform(0.0, 0.4, n)
    q[:, 5] = rng.uniform(-np.pi, np.pi, n)
    q[:, 6:] = rng.uniform(0.6, 1.4, (n, 3))
    return q


def rate(fn, q: np.ndarray, seconds: float) -> float:
    """Best evaluations per second over five rounds."""
    best = 0.0
    for _ in range(5):
        calls, start = 0, time.perf_counter()
        while (elapsed := time.perf_counter() - start) < seconds / 5 or calls == 0:
            fn(q)
            calls += 1
        best = max(best, calls * len(q) / elapsed)
    return best


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=1.0, help="time per measurement")
    args = parser.parse_args()
    system = CableSystem.from_spec()
    rng = np.random.default_rng(0)
    compiled = lambda q: configuration_cost(system, q)  # noqa: E731
    reference = lambda q: cost_from_report(system, evaluate_statics(system, q))  # noqa: E731
    compiled(sample(2, rng))  # load the kernel before timing
    print(
        f"machine: {platform.machine()} {platform.processor() or ''}, python "
        f"{platform.python_version()}, numpy {np.__version__}"
    )
    print(
        f"{'batch':>6} {'compiled [1/s]':>15} {'per call [us]':>14} {'numpy [1/s]':>13} "
        f"{'per call [us]':>14} {'ratio':>7}"
    )
    for n in (1, 64, 4096):
        q = sample(n, rng)
        fast, slow = rate(compiled, q, args.seconds), rate(reference, q, args.seconds)
        print(
            f"{n:>6} {fast:>15,.0f} {n / fast * 1e6:>14.1f} {slow:>13,.0f} "
            f"{n / slow * 1e6:>14.1f} {fast / slow:>7.1f}"
        )


if __name__ == "__main__":
    main()
