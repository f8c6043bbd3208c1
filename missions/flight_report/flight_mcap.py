"""A flight as an MCAP log for Foxglove: the load as the drones carried it, and the report's
figures over time (``missions.export.mission_mcap`` writes it).

Topics (log time: the first release, on the flight log's clock, plus mission time):

- ``/scene``, ``/tf``, ``/drone{k}/fix``: the obstacles, and the crane rebuilt from the
  drones of the report's safety source (the truth where there is one) at every report
  sample whose pose converged;
- ``/flight/estimated`` and ``/flight/true``: per sample, each drone's distance from where
  the model put it (``error_in_time``), the inter-drone distance error, the least slack,
  overload and thrust margins, the clearance to the real obstacles and whether the sample
  was safe;
- ``/flight/progress``: each drone's progress along the plan (plan time, or null where it
  is not defined);
- metadata ``report`` (every figure and the verdict, ``report.json`` without its series)
  and ``task``.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np

from missions.export.mission_mcap import LogInputs, write_mcap
from missions.flight_report.planned_flight import PlannedFlight
from missions.flight_report.report import FlightReport
from missions.trajectory.tracks import Track

#: The per-sample figures of each source, by the name they have in the log.
FIGURES = ("error_in_time", "inter_drone_error", "slack_margin", "overload_margin",
           "thrust_margin", "clearance", "safe")  # fmt: skip


def _plain(value: Any) -> Any:
    """``value`` with every NaN or infinity as None (JSON has neither)."""
    if isinstance(value, float) and not math.isfinite(value):
        return None
    if isinstance(value, dict):
        return {k: _plain(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_plain(v) for v in value]
    return value


def write_flight_mcap(report: FlightReport, plan: PlannedFlight, path: Path) -> Path:
    """Write the flight's log (module docstring); returns its path."""
    source = "true" if report.true is not None else "estimated"
    series = report.series
    time = np.asarray(series["time"]["mission"], dtype=float)
    q = np.asarray(series[source]["configurations"], dtype=float)
    drones = np.asarray(series[source]["drones_enu"], dtype=float)
    posed = np.isfinite(q).all(axis=1)
    records: list[tuple[float, str, dict[str, Any]]] = []
    for name in ("estimated", "true"):
        figures = series.get(name)
        if not figures:
            continue
        for n, when in enumerate(time):
            body = {"time": float(when), **{f: _plain(figures[f][n]) for f in FIGURES}}
            records.append((float(when), f"/flight/{name}", body))
    for n, when in enumerate(time):
        body = {"time": float(when), "plan_time": _plain(series["progress"]["plan_time"][n])}
        records.append((float(when), "/flight/progress", body))
    summary = {key: value for key, value in report.as_dict().items() if key != "series"}
    task = plan.task
    problem = plan.problem
    return write_mcap(
        path,
        LogInputs(
            system=problem.system,
            scene=problem.scene,
            track=Track(time[posed], q[posed], drones[posed]),
            annotations=None,
            missions=(),
            options=task.mission,
            start_ns=round(report.release_log_time * 1e9),
            metadata={"report": _plain(summary), "task": task.model_dump(mode="json")},
            records=records,
        ),
    )
