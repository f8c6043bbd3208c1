"""The planner benchmark of the paper's Table I and Fig. 6, run over seeds in parallel.

Each run plans one scene with one planner and one seed (:func:`run_one`, a picklable
top-level function, so any :class:`concurrent.futures.Executor` can run it), smooths the
path and measures it. :func:`summarize` gives the Table I columns per scene and planner:
means (as the paper reports) and medians of avgC, maxC, MW, IC over the solved runs, of the
time t over all runs, and of N and X, with the success rate.
"""

from __future__ import annotations

import csv
import io
import json
import math
import os
from collections.abc import Iterable, Sequence
from concurrent.futures import Executor
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

from flycrane.planning.planners import PlannerOptions, plan
from flycrane.planning.problem import PlanningProblem

#: Table I columns: (key, header, format)
COLUMNS = (
    ("avg_cost", "avgC", ".3g"),
    ("max_cost", "maxC", ".3g"),
    ("mechanical_work", "MW", ".3g"),
    ("cost_integral", "IC", ".3g"),
    ("time", "t (s)", ".2f"),
    ("nodes", "N", ".0f"),
    ("attempts", "X", ".0f"),
)


@dataclass(frozen=True)
class RunRecord:
    """One planning run of the benchmark."""

    scene: str
    planner: str
    seed: int
    status: str
    time: float  #: planner seconds (smoothing excluded)
    nodes: int
    attempts: int
    smoothing_time: float
    avg_cost: float | None = None
    max_cost: float | None = None
    mechanical_work: float | None = None
    cost_integral: float | None = None
    path: tuple[tuple[float, ...], ...] = ()  #: smoothed path, for the profiles

    @property
    def solved(self) -> bool:
        return self.status == "exact_solution"


def run_one(scene: str, options: PlannerOptions) -> RunRecord:
    """Plan ``scene`` (a shipped scene name) once; the problem is built in this process."""
    problem = PlanningProblem.named(scene)
    outcome = plan(problem.space, problem.validity, problem.start, problem.goal, options)
    stats = outcome.result.statistics
    metrics = outcome.metrics
    return RunRecord(
        scene=scene,
        planner=options.algorithm_for(problem.validity.payload_meshes),
        seed=options.seed,
        status=outcome.result.status.value,
        time=stats.time,
        nodes=stats.nodes,
        attempts=stats.expansion_attempts,
        smoothing_time=outcome.smoothing_time,
        avg_cost=metrics.avg_cost if metrics else None,
        max_cost=metrics.max_cost if metrics else None,
        mechanical_work=metrics.mechanical_work if metrics else None,
        cost_integral=metrics.cost_integral if metrics else None,
        path=tuple(tuple(map(float, q)) for q in outcome.path),
    )


def run_benchmark(
    executor: Executor,
    scenes: Sequence[str],
    planners: Sequence[str],
    runs: int,
    time_budget: float,
    base: PlannerOptions | None = None,
) -> Iterable[RunRecord]:
    """Submit every (scene, planner, seed) run and yield records as they finish."""
    from concurrent.futures import as_completed

    base = base or PlannerOptions()
    futures = [
        executor.submit(
            run_one,
            scene,
            base.model_copy(
                update={"algorithm": planner, "seed": seed, "time_budget": time_budget}
            ),
        )
        for scene in scenes
        for planner in planners
        for seed in range(runs)
    ]
    for future in as_completed(futures):
        yield future.result()


def _stat(values: list[float], how: str) -> float:
    if not values:
        return math.nan
    return float(np.mean(values) if how == "mean" else np.median(values))


def summarize(records: Sequence[RunRecord]) -> list[dict]:
    """Table I rows: one per (scene, planner), in first-seen order."""
    rows = []
    keys = dict.fromkeys((r.scene, r.planner) for r in records)
    for scene, planner in keys:
        group = [r for r in records if (r.scene, r.planner) == (scene, planner)]
        solved = [r for r in group if r.solved]
        row: dict = {
            "scene": scene,
            "planner": planner,
            "runs": len(group),
            "solved": len(solved),
            "success_rate": len(solved) / len(group),
        }
        for key, _, _ in COLUMNS:
            pool = group if key in ("time", "nodes", "attempts") else solved
            values = [float(getattr(r, key)) for r in pool]
            row[f"mean_{key}"] = _stat(values, "mean")
            row[f"median_{key}"] = _stat(values, "median")
        rows.append(row)
    return rows


def format_table(rows: Sequence[dict]) -> str:
    """The summary as a text table (means, then medians in brackets)."""
    header = f"{'scene':<8} {'planner':<10} {'solved':>8} " + " ".join(
        f"{h:>22}" for _, h, _ in COLUMNS
    )
    lines = [header, "-" * len(header)]
    for row in rows:
        cells = " ".join(
            f"{format(row['mean_' + k], f):>10} [{format(row['median_' + k], f):>9}]"
            for k, _, f in COLUMNS
        )
        solved = f"{row['solved']}/{row['runs']}"
        lines.append(f"{row['scene']:<8} {row['planner']:<10} {solved:>8} {cells}")
    lines.append("mean [median]; cost columns over solved runs, t/N/X over all runs")
    return "\n".join(lines)


def format_margins(margins: dict[tuple[str, str], list]) -> str:
    """Fig. 6's least margins per (scene, planner) over its solved runs
    (:func:`flycrane.analysis.profiles.least_margins`): median and worst run, in N."""
    header = f"{'scene':<14} {'planner':<16} " + " ".join(
        f"{name:>22}" for name in ("slack t_lo-f_lo", "headroom f_hi-t_hi", "thrust h-m")
    )
    lines = [header, "-" * len(header)]
    for (scene, planner), runs in margins.items():
        cells = []
        for field in ("slack", "headroom", "thrust"):
            values = [getattr(m, field) for m in runs]
            cells.append(
                f"{np.median(values):>10.2f} [{np.min(values):>9.2f}]" if values else f"{'-':>22}"
            )
        lines.append(f"{scene:<14} {planner:<16} " + " ".join(cells))
    lines.append("least margin along each path [N]: median over the solved runs [worst run]")
    return "\n".join(lines)


def write_results(records: Sequence[RunRecord], rows: Sequence[dict], out: Path) -> None:
    """runs.csv (one line per run), summary.json (table rows and runs with paths)."""
    out.mkdir(parents=True, exist_ok=True)
    fields = [f for f in RunRecord.__dataclass_fields__ if f != "path"]
    table = io.StringIO(newline="")
    writer = csv.DictWriter(table, fieldnames=fields)
    writer.writeheader()
    for record in records:
        writer.writerow({f: getattr(record, f) for f in fields})
    _write_whole(out / "runs.csv", table.getvalue())
    clean = lambda v: None if isinstance(v, float) and math.isnan(v) else v  # noqa: E731
    summary = {
        "table": [{k: clean(v) for k, v in row.items()} for row in rows],
        "runs": [asdict(r) for r in records],
    }
    _write_whole(out / "summary.json", json.dumps(summary, indent=1))


def _write_whole(path: Path, text: str) -> None:
    """``text`` into ``path`` whole or not at all: a full disk leaves no half a file that
    reads as a result. An error names the file (a full disk's does not)."""
    partial = path.with_name(f".{path.name}.partial")
    try:
        with partial.open("w", encoding="utf-8", newline="") as handle:
            handle.write(text)
        os.replace(partial, path)
    except OSError as error:
        partial.unlink(missing_ok=True)
        raise OSError(error.errno, error.strerror, str(path)) from error
