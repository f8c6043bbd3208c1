"""How far the drones' position errors can lower a configuration's statics margins, and its
robust margins: each margin less that bound.

The margins (slack and overload of each cable, eq. 4-6, and thrust of each drone, eq. 7:
design.md section 5) are functions of the configuration, and the configuration of the
three drones' positions A (the direct kinematics). To first order a drone error dA changes
margin j by ``(dm_j / dA) dA``; the derivative is taken by central differences through the
direct kinematics (:func:`margin_gradients`), which needs no parametrization of the
platform's rotation (the tilt-torsion angles are singular upright). An error the three
drones share moves the platform rigidly, under gravity alone, and leaves every margin as
it is (the tests hold this); only each drone's own error counts, within a horizontal
radius h and a vertical half-height v, so margin j falls by at most (:func:`margin_bounds`)

    sum_k (||(dm_j / dA_k)[:2]|| h + |(dm_j / dA_k)[2]| v).

Assumptions as :mod:`flycrane.model.pose_error`'s: taut cables, errors small against the
cables, and the drones' errors independent. The bound is of first order, and tight: the
three drones' worst errors add exactly at the corners of their bounds, where the
second-order term can take the exact fall somewhat beyond it
(``tests/flycrane/model/test_robust_statics.py`` holds it against the exact direct
kinematics and statics of sampled errors; BENCHMARKS.md "Robust statics margins").
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from flycrane.model.cable_system import CableSystem
from flycrane.model.direct_kinematics import configuration_from_drone_positions
from flycrane.model.kinematics import as_configurations, drone_positions_from_configuration
from flycrane.model.statics import StaticsReport, evaluate_statics

#: Central-difference step of a drone coordinate [m]: the margins are smooth on this scale
#: and the direct kinematics converges to 1e-10 m.
STEP = 1e-4
#: Names of the margins in the order of their columns (cable or drone, 1-based).
MARGIN_NAMES = tuple(
    [f"slack of cable {i}" for i in range(1, 7)]
    + [f"overload of cable {i}" for i in range(1, 7)]
    + [f"thrust of drone {k}" for k in range(1, 4)]
)


def margins(report: StaticsReport) -> NDArray[np.float64]:
    """Slack, overload and thrust margins side by side [N]: (N, 15)."""
    return np.concatenate(
        [report.slack_margin, report.overload_margin, report.thrust_margin], axis=1
    )


def margin_gradients(system: CableSystem, q: ArrayLike) -> NDArray[np.float64]:
    """d(margins) / d(A_1, A_2, A_3) at configurations q (N, 9): (N, 15, 9) [N/m]."""
    q = as_configurations(q)
    drones = drone_positions_from_configuration(system, q).reshape(len(q), 9)
    gradients = np.empty((len(q), 15, 9))
    for j in range(9):
        step = np.zeros(9)
        step[j] = STEP
        moved = [
            configuration_from_drone_positions(system, (drones + s).reshape(-1, 3, 3), q).q
            for s in (step, -step)
        ]
        ahead, behind = (margins(evaluate_statics(system, m)) for m in moved)
        gradients[:, :, j] = (ahead - behind) / (2 * STEP)
    return gradients


def margin_bounds(
    system: CableSystem, q: ArrayLike, own: tuple[float, float]
) -> NDArray[np.float64]:
    """How much each margin can fall [N] when each drone is off by its own error within
    ``own`` (horizontal radius, vertical half-height) [m]: (N, 15) (module docstring);
    +inf where a margin is not finite (a singular configuration)."""
    per_drone = margin_gradients(system, q).reshape(-1, 15, 3, 3)
    h, v = own
    bound = (np.linalg.norm(per_drone[..., :2], axis=-1) * h
             + np.abs(per_drone[..., 2]) * v).sum(axis=-1)  # fmt: skip
    return np.where(np.isfinite(bound), bound, np.inf)


@dataclass(frozen=True)
class RobustStatics:
    """Statics margins of configurations and what the drones' errors can take of them."""

    margin: NDArray[np.float64]  #: (N, 15) [N], columns :data:`MARGIN_NAMES`
    bound: NDArray[np.float64]  #: (N, 15) [N]

    @classmethod
    def of(cls, system: CableSystem, q: ArrayLike, own: tuple[float, float]) -> RobustStatics:
        q = as_configurations(q)
        return cls(margins(evaluate_statics(system, q)), margin_bounds(system, q, own))

    @property
    def robust(self) -> NDArray[np.float64]:
        """Each margin less its bound [N]: (N, 15)."""
        return self.margin - self.bound

    def least(self) -> tuple[float, str, int]:
        """The least robust margin [N], which margin it is and at which configuration."""
        row, column = np.unravel_index(int(np.argmin(self.robust)), self.robust.shape)
        return float(self.robust[row, column]), MARGIN_NAMES[column], int(row)
