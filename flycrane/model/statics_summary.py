"""Plain-data summaries of model results, shared by the CLI and the HTTP service."""

from __future__ import annotations

import numpy as np

from flycrane.model.cable_system import CableSystem
from flycrane.model.cost import CostForm, cost_from_report
from flycrane.model.feasibility import violations
from flycrane.model.kinematics import COORDINATES, drone_positions_from_configuration
from flycrane.model.statics import StaticsReport


def _finite(values) -> list[float | None]:
    """Floats, with +/-inf (singular or unbounded values) as None: JSON has no infinity."""
    return [float(v) if np.isfinite(v) else None for v in np.ravel(values)]


def statics_summary(
    system: CableSystem, report: StaticsReport, form: CostForm, row: int = 0
) -> dict:
    """Plain-data statics of one configuration (what ``--json`` prints)."""
    q = report.q[row]
    drones = drone_positions_from_configuration(system, q)[0]
    cost = float(cost_from_report(system, report, form)[row])
    return {
        "configuration": dict(zip(COORDINATES, map(float, q), strict=True)),
        "feasible": bool(report.feasible[row]),
        "singular": bool(report.singular[row]),
        "cost": cost if np.isfinite(cost) else None,
        "cost_form": str(form),
        "cables": [
            {
                "cable": i + 1,
                "nominal_tension": _finite(report.nominal_tension[row, i])[0],
                "half_width": _finite(report.half_width[row, i])[0],
                "tension_low": _finite(report.tension_low[row, i])[0],
                "tension_high": _finite(report.tension_high[row, i])[0],
                "tension_min": float(system.tension_min[i]),
                "tension_max": float(system.tension_max[i]),
                "slack_margin": _finite(report.slack_margin[row, i])[0],
                "overload_margin": _finite(report.overload_margin[row, i])[0],
            }
            for i in range(6)
        ],
        "drones": [
            {
                "drone": k + 1,
                "position": [float(v) for v in drones[k]],
                "nominal_thrust": _finite(report.nominal_thrust[row, k]),
                "thrust_bound": _finite(report.thrust_bound[row, k])[0],
                "max_thrust": float(system.max_thrusts[k]),
                "thrust_margin": _finite(report.thrust_margin[row, k])[0],
            }
            for k in range(3)
        ],
        "violations": [
            {
                "constraint": str(v.constraint),
                "index": v.index,
                "margin": _finite(v.margin)[0],
                "message": str(v),
            }
            for v in violations(report, row)
        ],
    }
