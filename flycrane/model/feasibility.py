"""Feasibility of configurations: every violated constraint, named, with its margin.

A configuration is feasible when J is non-singular, every cable's tension range over the
perturbation ellipsoid lies inside its rating (eq. 5-6), and every drone's worst-case thrust
is below its maximum (eq. 7) -- design.md section 5.
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import StrEnum

import numpy as np

from flycrane.model.statics import StaticsReport


class Constraint(StrEnum):
    """Kinds of statics constraint."""

    SINGULAR = "singular"  #: screw Jacobian singular: the platform is not held
    SLACK = "slack"  #: a cable may go slack (t_lo <= f_lo)
    OVERLOAD = "overload"  #: a cable may be overloaded (t_hi >= f_hi)
    THRUST = "thrust"  #: a drone may need more than its maximum thrust (m_k >= h_k)


@dataclass(frozen=True)
class Violation:
    """One violated constraint of one configuration.

    ``index`` is the 1-based cable (slack, overload) or drone (thrust) number, 0 for
    singular. ``value`` is the constrained quantity (t_lo, t_hi or m_k in N), ``limit`` its
    bound, and ``margin`` the signed distance to it (<= 0 means violated), in N.
    """

    constraint: Constraint
    index: int
    value: float
    limit: float
    margin: float

    def __str__(self) -> str:
        if self.constraint is Constraint.SINGULAR:
            return "screw Jacobian is singular (the cables do not hold the platform)"
        what = {
            Constraint.SLACK: f"cable {self.index}: lowest tension {self.value:.4g} N <= "
            f"minimum {self.limit:.4g} N",
            Constraint.OVERLOAD: f"cable {self.index}: highest tension {self.value:.4g} N >= "
            f"maximum {self.limit:.4g} N",
            Constraint.THRUST: f"drone {self.index}: worst-case thrust {self.value:.4g} N >= "
            f"maximum {self.limit:.4g} N",
        }[self.constraint]
        return f"{what} (margin {self.margin:.4g} N)"


def violations(report: StaticsReport, row: int = 0) -> list[Violation]:
    """Every violated constraint of configuration ``row`` of a report (empty if feasible)."""
    if report.singular[row]:
        return [Violation(Constraint.SINGULAR, 0, np.inf, np.inf, -np.inf)]
    found: list[Violation] = []
    checks = (
        (Constraint.SLACK, report.slack_margin[row], report.tension_low[row], -1.0),
        (Constraint.OVERLOAD, report.overload_margin[row], report.tension_high[row], 1.0),
        (Constraint.THRUST, report.thrust_margin[row], report.thrust_bound[row], 1.0),
    )
    for constraint, margins, values, side in checks:
        for i in np.flatnonzero(margins <= 0):
            # the limit sits a margin beyond the value: below it for slack, above otherwise
            limit = values[i] + side * margins[i]
            found.append(
                Violation(constraint, int(i) + 1, float(values[i]), float(limit), float(margins[i]))
            )
    return found
