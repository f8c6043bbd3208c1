"""Anytime improvement (issue 24, item 3): bitrrt's avgC with and without the refinement,
against RRT's, with Fig. 6's least margins and the time it takes.

    python benchmarks/anytime_improvement.py --runs 20

Per scene and seed, :func:`flycrane.planning.planners.plan` runs RRT (``rrt``, not
refined: the issue's reference), bitrrt as the default plans it (``improve_time`` 0) and
bitrrt refined (``--improve-time``, 5 s), one run after the other in this process.
The refinement keeps the robust margin of the position-error model ``--robust`` (default
``rtk``; ``none``: not kept), as the task pipeline does with the task's model.
The summary gives the median avgC of each, the ratio of RRT's median to bitrrt's with a 95 %
bootstrap interval (percentile, 2,000 resamples of each side's seeds), the least margins of
both bitrrt variants (Fig. 6's reading, :func:`flycrane.analysis.profiles.least_margins`,
and at the metrics resolution), the cost integral and length, and the time the refinement
adds. Then, for one seed, avgC after a given time of refinement.
"""

from __future__ import annotations

import argparse

import numpy as np
from bench_input import at_least_one

from flycrane.analysis.profiles import least_margins, path_profile
from flycrane.model.statics import evaluate_statics
from flycrane.planning.metrics import METRICS_RESOLUTION
from flycrane.planning.planners import PlannerOptions, PlanningOutcome, plan
from flycrane.planning.problem import PlanningProblem
from flycrane.planning.robust_clearance import RobustClearance
from missions.position_error import PRESETS

#: Per run: avgC, IC, length, Fig. 6's slack, headroom, thrust, the same at the metrics
#: resolution, smoothing (and refinement) time [s].
COLUMNS = ("avgC", "IC", "length", "slack", "headroom", "thrust", "slack@res", "headroom@res",
           "thrust@res", "smoothing")  # fmt: skip
VARIANTS = ("rrt", "bitrrt, improve 0", "bitrrt, improved")


def measured(problem: PlanningProblem, outcome: PlanningOutcome) -> list[float]:
    """One run's row of COLUMNS."""
    assert outcome.metrics is not None, outcome.result.reason
    fig6 = least_margins(path_profile(problem.system, problem.space, outcome.path), problem.system)
    report = evaluate_statics(
        problem.system, problem.space.discretize_path(outcome.path, METRICS_RESOLUTION)
    )
    m = outcome.metrics
    return [m.avg_cost, m.cost_integral, m.length, fig6.slack, fig6.headroom, fig6.thrust,
            report.slack_margin.min(), report.overload_margin.min(),
            report.thrust_margin.min(), outcome.smoothing_time]  # fmt: skip


def run(
    problem: PlanningProblem,
    seed: int,
    budget: float,
    improve: float,
    robust: RobustClearance | None,
) -> list:
    """Rows of the three variants for one seed."""
    variants = [("rrt", 0.0), ("bitrrt", 0.0), ("bitrrt", improve)]
    rows = []
    for algorithm, improve_time in variants:
        options = PlannerOptions(
            algorithm=algorithm, seed=seed, time_budget=budget, improve_time=improve_time
        )
        outcome = plan(
            problem.space, problem.validity, problem.start, problem.goal, options, robust=robust
        )
        rows.append(measured(problem, outcome))
    return rows


def ratio_interval(rrt: np.ndarray, bitrrt: np.ndarray, draws: int = 2000) -> str:
    """median(rrt) / median(bitrrt) with its 95 % percentile bootstrap interval."""
    rng = np.random.default_rng(0)
    mine = np.median(rrt[rng.integers(0, len(rrt), (draws, len(rrt)))], axis=1)
    theirs = np.median(bitrrt[rng.integers(0, len(bitrrt), (draws, len(bitrrt)))], axis=1)
    low, high = np.percentile(mine / theirs, [2.5, 97.5])
    return f"{np.median(rrt) / np.median(bitrrt):.2f} [{low:.2f}, {high:.2f}]"


def summary(scene: str, table: np.ndarray) -> None:
    """table: (seeds, 3 variants, COLUMNS)."""
    avg = table[:, :, 0]
    print(f"\n{scene}: median avgC  rrt {np.median(avg[:, 0]):.3g}  bitrrt (improve 0) "
          f"{np.median(avg[:, 1]):.3g}  bitrrt improved {np.median(avg[:, 2]):.3g}")  # fmt: skip
    print(f"  rrt / bitrrt (improve 0): {ratio_interval(avg[:, 0], avg[:, 1])}")
    print(f"  rrt / bitrrt improved:    {ratio_interval(avg[:, 0], avg[:, 2])}")
    print(f"  improved / improve 0, per seed: median {np.median(avg[:, 2] / avg[:, 1]):.3f}, "
          f"largest {np.max(avg[:, 2] / avg[:, 1]):.3f}; unchanged in "
          f"{np.sum(avg[:, 2] == avg[:, 1])} of {len(avg)} seeds")  # fmt: skip
    for k, name in enumerate(COLUMNS[1:9], start=1):
        before, after = table[:, 1, k], table[:, 2, k]
        print(f"  {name:<13} improve 0 median {np.median(before):9.4g} [worst {before.min():8.4g}]"
              f"  improved {np.median(after):9.4g} [worst {after.min():8.4g}]"
              f"  per-seed difference median {np.median(after - before):+.3g}, "
              f"least {np.min(after - before):+.3g}")  # fmt: skip
    extra = table[:, 2, 9] - table[:, 1, 9]
    print(f"  extra time [s]: median {np.median(extra):.2f}, p90 {np.percentile(extra, 90):.2f}, "
          f"max {extra.max():.2f} (smoothing+polish without: median "
          f"{np.median(table[:, 1, 9]):.2f})")  # fmt: skip


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenes", nargs="+", default=["rescue", "puzzle"])
    parser.add_argument("--runs", type=at_least_one, default=20, help="seeds per scene (from 0)")
    parser.add_argument("--budget", type=float, default=60.0, help="planning time limit [s]")
    parser.add_argument("--improve-time", type=float, default=5.0, help="refinement cap [s]")
    parser.add_argument("--robust", default="rtk", choices=[*sorted(PRESETS), "none"])
    parser.add_argument("--curve-seed", type=int, default=0)
    parser.add_argument("--curve", type=float, nargs="+", default=[0.1, 0.25, 0.5, 1, 2, 4])
    args = parser.parse_args()
    for scene in args.scenes:
        problem = PlanningProblem.named(scene)
        robust = None
        if args.robust != "none":
            model = PRESETS[args.robust]
            common = (model.common_horizontal, model.common_vertical)
            robust = RobustClearance(problem.validity.with_clearance(0.0), common, model.own)
        print(f"{scene}: seed, avgC of {', '.join(VARIANTS)}; refinement time [s]")
        rows = []
        for seed in range(args.runs):
            rows.append(run(problem, seed, args.budget, args.improve_time, robust))
            r = rows[-1]
            print(f"  {seed:3d}  {r[0][0]:.3g}  {r[1][0]:.3g}  {r[2][0]:.3g}  "
                  f"{r[2][9] - r[1][9]:.2f}", flush=True)  # fmt: skip
        summary(scene, np.array(rows))
        curve = []
        for improve_time in args.curve:
            options = PlannerOptions(seed=args.curve_seed, improve_time=improve_time)
            outcome = plan(
                problem.space, problem.validity, problem.start, problem.goal, options, robust=robust
            )
            assert outcome.metrics is not None
            curve.append(f"{improve_time:g} s: {outcome.metrics.avg_cost:.3g}")
        print(f"  seed {args.curve_seed}, avgC after refining for " + ", ".join(curve) + "\n")


if __name__ == "__main__":
    main()
