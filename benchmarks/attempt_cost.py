"""Where bitrrt's time per expansion attempt goes (issue 24, item 4: the aim is 30 us).

    .venv/bin/python benchmarks/attempt_cost.py [--scenes puzzle rescue] [--seeds 10]

Two measures per scene, in one process:

- one configuration's check inside a compiled loop (no Python between calls): the whole
  state check (bounds, statics, collisions, :func:`~flycrane.planning.validity_kernel.
  state_check`), the statics alone and the collisions alone, on configurations uniform in
  the sampling bounds and on ones near the task's start (5 cm noise), where trees grow;
- bitrrt's time per expansion attempt (the run's time over its attempts; an attempt is one
  extension of the current tree and, when it succeeds, the other tree's connection) and the
  configurations it checked per attempt (counted by the checker,
  :meth:`~flycrane.planning.validity_kernel.CompiledValidity.checked`), with its defaults
  and with one of its extension's parts turned off at a time (the alpha repair, the
  partial extensions, reshape-first), the variants run seed by seed in turn.

The attempt's time over its checks bounds what one check costs inside the planner, where
the configurations lie near obstacles and the calls come from the extension's code.
"""

from __future__ import annotations

import argparse
import math
import statistics
import time
from dataclasses import replace

import numpy as np
from bench_input import at_least_one

from flycrane.kernels import kernel
from flycrane.model.statics_kernel import statics_row
from flycrane.planning.algorithms.bitrrt import BiTRRT
from flycrane.planning.planners import PlannerOptions
from flycrane.planning.result import TerminationCondition
from flycrane.planning.validity_kernel import state_check
from flycrane.world.collision_kernel import collision_free_row
from missions.task.resolve import resolve_task
from missions.task.spec import TaskSpec


@kernel()
def _state_checks(q, model, work) -> int:
    valid = 0
    for i in range(q.shape[0]):
        valid += state_check(q[i], model, work, True)[1]
    return valid


@kernel()
def _statics(q, model, work) -> int:
    feasible = 0
    for i in range(q.shape[0]):
        feasible += statics_row(q[i], model[1], work[1], work[2], work[3], work[0]) < math.inf
    return feasible


@kernel()
def _collisions(q, model, work) -> int:
    free = 0
    for i in range(q.shape[0]):
        free += collision_free_row(q[i], model[2], model[3], work[4:11])
    return free


def per_configuration(kernel, q, model, work) -> tuple[float, float]:
    """(us per configuration, share counted) of a compiled loop over q."""
    kernel(q[:10], model, work)  # compiled and warm
    start = time.perf_counter()
    count = kernel(q, model, work)
    return (time.perf_counter() - start) / len(q) * 1e6, count / len(q)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenes", nargs="+", default=["puzzle", "rescue"])
    parser.add_argument("--seeds", type=at_least_one, default=10)
    parser.add_argument("--count", type=int, default=20_000, help="configurations per loop")
    parser.add_argument("--budget", type=float, default=30.0, help="[s] per bitrrt run")
    args = parser.parse_args()
    for scene in args.scenes:
        resolved = resolve_task(TaskSpec(scene=scene))
        validity = resolved.checkers.planning
        model, work = validity.compiled.model, validity.work
        rng = np.random.default_rng(0)
        sets = {
            "uniform": resolved.problem.space.sample_uniform(rng, args.count),
            "near the start": resolved.start + rng.normal(0.0, 0.05, (args.count, 9)),
        }
        for name, q in sets.items():
            whole, valid = per_configuration(_state_checks, q, model, work)
            statics, feasible = per_configuration(_statics, q, model, work)
            collisions, free = per_configuration(_collisions, q, model, work)
            print(f"{scene}, {name}: state check {whole:.2f} us ({valid:.0%} valid), statics "
                  f"{statics:.2f} us ({feasible:.0%} feasible), collisions {collisions:.2f} us "
                  f"({free:.0%} free)")  # fmt: skip
        base = PlannerOptions().bitrrt_config()
        variants = {
            "default": base,
            "no alpha repair": replace(base, repair_share=0.0),
            "no partial extensions": replace(base, partial=0.0),
            "no reshape-first": replace(base, reshape_first=False),
        }
        runs: dict[str, list[tuple[float, float, bool, float]]] = {name: [] for name in variants}
        # compiled (or loaded from numba's cache) before anything is timed: a seed not measured
        BiTRRT(resolved.problem.space, validity, base).solve(
            resolved.start, resolved.goal, TerminationCondition(600.0), seed=args.seeds
        )
        for seed in range(args.seeds):
            for name, config in variants.items():
                planner = BiTRRT(resolved.problem.space, validity, config)
                checked = validity.compiled.checked(work)
                start = time.perf_counter()
                result = planner.solve(
                    resolved.start, resolved.goal, TerminationCondition(args.budget), seed=seed
                )
                elapsed = time.perf_counter() - start
                attempts = max(result.statistics.expansion_attempts, 1)
                checks = (validity.compiled.checked(work) - checked) / attempts
                runs[name].append((elapsed / attempts * 1e6, checks, result.status.solved,
                                   elapsed))  # fmt: skip
        for name, rows in runs.items():
            per_attempt = statistics.median(r[0] for r in rows)
            checks = statistics.median(r[1] for r in rows)
            print(f"{scene}, bitrrt {name}: {per_attempt:.0f} us per attempt, {checks:.1f} "
                  f"configurations checked per attempt ({per_attempt / checks:.1f} us each at "
                  f"most; medians of {len(rows)}), solved {sum(r[2] for r in rows)}/{len(rows)}, "
                  f"median {statistics.median(r[3] for r in rows):.3f} s")  # fmt: skip


if __name__ == "__main__":
    main()
