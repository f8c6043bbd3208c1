"""Validity checks per second, compiled against python-fcl, and T-RRT's time per expansion.

    python benchmarks/validity_throughput.py [--count 4000] [--motions 400] [--seeds 3] \
        [--scenes rescue puzzle site]

For the Rescue, the Puzzle and the ``site`` (the Rescue among four buildings given as
16320 triangle faces, kept at an 8 cm clearance as the default position-error model asks),
in one process and on the same configurations:

- single-configuration checks (``is_valid`` of one configuration, as a planner's state check)
  and motion checks (every configuration of a local path at the checker's resolution, as
  ``motion_is_valid``) with the compiled checker (:class:`ValidityChecker`) and with the
  reference it replaced: the statics cost, the sampling bounds and python-fcl's
  :class:`CollisionChecker` (what ``ValidityChecker`` did before, and did for meshes until
  the compiled checker took their faces);
- how often the two disagree (the compiled path may only call contact what fcl calls free
  within 1e-5 m of touching: ``tests/flycrane/test_collision_kernel.py``);
- T-RRT on the same seeds with each checker: time per expansion attempt.

Configurations are uniform in each scene's sampling bounds; motions join pairs of them,
shortened to one planner step so that they are the motions a planner checks.
"""

from __future__ import annotations

import argparse
import statistics
import time

import numpy as np
from bench_input import at_least_one
from numpy.typing import NDArray

from flycrane.model.statics_kernel import configuration_cost
from flycrane.planning.algorithms.trrt import STEP_FRACTION, TRRT
from flycrane.planning.problem import PlanningProblem
from flycrane.planning.result import TerminationCondition
from flycrane.planning.validity import ValidityChecker
from flycrane.world.scene import SCENES_DIR


class FclValidity:
    """The reference: statics cost, bounds, then python-fcl on what is feasible."""

    def __init__(self, checker: ValidityChecker) -> None:
        self.checker, self.space = checker, checker.space

    def cost(self, q: NDArray) -> NDArray:
        cost = configuration_cost(self.checker.system, q)
        cost[~self.space.contains(q)] = np.inf
        return cost

    def is_valid(self, q: NDArray) -> NDArray:
        valid = np.isfinite(self.cost(q))
        if valid.any():
            valid[valid] = self.checker.collision.collision_free(q[valid])
        return valid

    def motion_is_valid(self, a: NDArray, b: NDArray) -> bool:
        path = self.space.discretize(a, b, self.checker.resolution)
        if not np.all(np.isfinite(self.cost(path))):
            return False
        return self.checker.collision.first_collision(path) is None

    def describe_invalid(self, q: NDArray) -> str:
        return self.checker.describe_invalid(q)


def rate(count: int, seconds: float) -> str:
    return f"{count / seconds:10,.0f}/s ({1e6 * seconds / count:7.1f} us)"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--count", type=int, default=4000, help="single checks per checker")
    parser.add_argument("--motions", type=int, default=400, help="motions per checker")
    parser.add_argument("--seeds", type=at_least_one, default=3, help="T-RRT seeds per checker")
    parser.add_argument("--budget", type=float, default=60.0, help="T-RRT seconds per run")
    parser.add_argument("--scenes", nargs="+", default=["rescue", "puzzle", "site"])
    args = parser.parse_args()
    for name in args.scenes:
        problem = PlanningProblem.named(name)
        if name == "site":  # the clearance the default position-error model asks for
            collision = problem.scene.collision.model_copy(update={"obstacle_clearance": 0.08})
            scene = problem.scene.model_copy(update={"collision": collision})
            raised = [np.asarray(q, dtype=float) + [0, 0, 0.1, 0, 0, 0, 0, 0, 0]
                      for q in (scene.start, scene.goal)]  # clear of the 8 cm  # fmt: skip
            problem = PlanningProblem.from_scene(scene, None, SCENES_DIR, *raised)
        compiled, space = problem.validity, problem.space
        reference = FclValidity(compiled)
        rng = np.random.default_rng(0)
        q = space.sample_uniform(rng, args.count)
        step = STEP_FRACTION * space.maximum_extent
        a, towards = (
            space.sample_uniform(rng, args.motions),
            space.sample_uniform(rng, args.motions),
        )
        reach = np.minimum(1.0, step / space.distance(a, towards))
        b = np.stack(
            [space.interpolate(x, y, [t])[0] for x, y, t in zip(a, towards, reach, strict=True)]
        )
        points = sum(
            len(space.discretize(x, y, compiled.resolution)) for x, y in zip(a, b, strict=True)
        )
        checkers = {"compiled": compiled, "fcl": reference}
        for checker in checkers.values():  # load kernels and fcl objects
            checker.is_valid(q[:1])
            checker.motion_is_valid(a[0], b[0])
        answers = {}
        for label, checker in checkers.items():
            clock = time.perf_counter()
            single = np.array([checker.is_valid(q[i : i + 1])[0] for i in range(len(q))])
            single_s = time.perf_counter() - clock
            clock = time.perf_counter()
            motion = np.array([checker.motion_is_valid(x, y) for x, y in zip(a, b, strict=True)])
            motion_s = time.perf_counter() - clock
            answers[label] = (single, motion)
            print(
                f"{name:6s} {label:8s} single {rate(len(q), single_s)}, {single.mean():4.0%} "
                f"valid; motions {rate(points, motion_s)} configurations, "
                f"{motion.mean():4.0%} valid ({points / len(a):.0f} configurations each)"
            )
        for kind, index in (("single", 0), ("motion", 1)):
            mine, theirs = answers["compiled"][index], answers["fcl"][index]
            print(
                f"{name:6s} {kind} disagreements: {np.sum(mine & ~theirs)} compiled-valid/"
                f"fcl-invalid, {np.sum(~mine & theirs)} compiled-invalid/fcl-valid"
            )
        per_attempt = {}
        for label, checker in checkers.items():
            planner = TRRT(space, checker)
            times = []
            for seed in range(args.seeds):
                result = planner.solve(
                    problem.start, problem.goal, TerminationCondition(args.budget), seed=seed
                )
                stats = result.statistics
                times.append(stats.time / max(stats.expansion_attempts, 1))
                print(
                    f"{name:6s} {label:8s} T-RRT seed {seed}: {result.status.name}, "
                    f"{stats.time:6.2f} s, {stats.expansion_attempts} attempts, "
                    f"{1e6 * times[-1]:7.1f} us per attempt"
                )
            per_attempt[label] = statistics.median(times)
        print(
            f"{name:6s} median time per expansion attempt: compiled "
            f"{1e6 * per_attempt['compiled']:.1f} us, fcl {1e6 * per_attempt['fcl']:.1f} us "
            f"({per_attempt['fcl'] / per_attempt['compiled']:.1f}x)"
        )


if __name__ == "__main__":
    main()
