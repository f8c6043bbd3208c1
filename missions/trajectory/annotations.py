"""Per-waypoint annotations (design.md s.8): what the load and the drones feel there."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from flycrane.model.cable_system import CableSystem
from flycrane.model.cost import cost_from_report
from flycrane.model.statics import evaluate_statics


@dataclass(frozen=True)
class Annotations:
    """Statics at K waypoints. Forces in N, drones and cables 0-based along the axes."""

    time: NDArray[np.float64]  #: (K,) from mission start [s]
    thrust: NDArray[np.float64]  #: (K, 3, 3) nominal thrust vector per drone (ENU)
    thrust_magnitude: NDArray[np.float64]  #: (K, 3) |thrust|
    thrust_bound: NDArray[np.float64]  #: (K, 3) worst case over the perturbations, m_k
    thrust_margin: NDArray[np.float64]  #: (K, 3) h_k - m_k
    tension: NDArray[np.float64]  #: (K, 6) nominal f0
    tension_low: NDArray[np.float64]  #: (K, 6) t_lo
    tension_high: NDArray[np.float64]  #: (K, 6) t_hi
    cost: NDArray[np.float64]  #: (K,) c(q), normalized form

    def records(self) -> list[dict]:
        """One plain dict per waypoint (JSON, MCAP); infinite values as None."""

        def clean(values: NDArray) -> list:
            return [float(v) if np.isfinite(v) else None for v in np.ravel(values)]

        return [
            {
                "waypoint": k,
                "time": float(self.time[k]),
                "cost": clean(self.cost[k])[0],
                "drones": [
                    {
                        "drone": j + 1,
                        "thrust": clean(self.thrust[k, j]),
                        "thrust_magnitude": clean(self.thrust_magnitude[k, j])[0],
                        "thrust_bound": clean(self.thrust_bound[k, j])[0],
                        "thrust_margin": clean(self.thrust_margin[k, j])[0],
                    }
                    for j in range(3)
                ],
                "cables": [
                    {
                        "cable": i + 1,
                        "tension": clean(self.tension[k, i])[0],
                        "tension_low": clean(self.tension_low[k, i])[0],
                        "tension_high": clean(self.tension_high[k, i])[0],
                    }
                    for i in range(6)
                ],
            }
            for k in range(len(self.time))
        ]


def annotate(system: CableSystem, time: NDArray, q: NDArray) -> Annotations:
    """Annotations of configurations q (K, 9) reached at times (K,)."""
    report = evaluate_statics(system, q)
    return Annotations(
        time=np.asarray(time, dtype=float),
        thrust=report.nominal_thrust,
        thrust_magnitude=np.linalg.norm(report.nominal_thrust, axis=-1),
        thrust_bound=report.thrust_bound,
        thrust_margin=report.thrust_margin,
        tension=report.nominal_tension,
        tension_low=report.tension_low,
        tension_high=report.tension_high,
        cost=cost_from_report(system, report),
    )
