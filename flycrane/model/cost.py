"""The configuration cost (design.md section 5; paper eq. 8).

Normalized form (the default)::

    c(q) = 1 / ( prod_k (h_k - m_k) / h_k
                 * prod_i (t_lo_i - f_lo_i) / (f_hi_i - f_lo_i)
                          * (f_hi_i - t_hi_i) / (f_hi_i - f_lo_i) )

Every factor is a margin divided by its range, so c is dimensionless and c >= 1 on feasible
configurations. The raw form drops the divisions (the paper's units, N^-15). Both are +inf
wherever a margin is <= 0 or J is singular. The product is taken as a sum of logarithms so
that fifteen small margins neither underflow nor warn.
"""

from __future__ import annotations

from enum import StrEnum

import numpy as np
from numpy.typing import NDArray

from flycrane.model.cable_system import CableSystem
from flycrane.model.statics import StaticsReport


class CostForm(StrEnum):
    """Which form of eq. 8 to evaluate."""

    NORMALIZED = "normalized"
    RAW = "raw"


def cost_margin_factors(
    system: CableSystem, report: StaticsReport, form: CostForm = CostForm.NORMALIZED
) -> NDArray[np.float64]:
    """The 15 factors of eq. 8 per configuration: 3 thrust, 6 slack, 6 overload, (N, 15)."""
    factors = np.concatenate(
        [report.thrust_margin, report.slack_margin, report.overload_margin], axis=1
    )
    if CostForm(form) is CostForm.NORMALIZED:
        tension_range = system.tension_max - system.tension_min
        factors = factors / np.concatenate([system.max_thrusts, tension_range, tension_range])
    return factors


def cost_from_report(
    system: CableSystem, report: StaticsReport, form: CostForm = CostForm.NORMALIZED
) -> NDArray[np.float64]:
    """Cost c(q) of each configuration of a statics report, shape (N,); +inf if infeasible."""
    factors = cost_margin_factors(system, report, form)
    ok = ~report.singular & np.all(factors > 0.0, axis=1)
    log_cost = np.full(len(factors), np.inf)
    log_cost[ok] = -np.log(factors[ok]).sum(axis=1)
    with np.errstate(over="ignore"):  # exp overflows to +inf on purpose: cost beyond 1e308
        return np.exp(log_cost)
