"""Tension and thrust profiles along paths, and their plots (the paper's Fig. 6).

A path is split into ``steps`` equal parts of its state-space length; at each of the
``steps + 1`` configurations we take the nominal tension of every cable, the tension range
[t_lo, t_hi] over the perturbation ellipsoid, and the nominal and worst-case thrust of every
drone. Fig. 6 of the paper plots, per step, the band from the smallest to the largest value
over all cables (drones) and over all paths of a planner; :func:`plot_profile_bands` draws
that band per planner, and :func:`plot_path_profile` the curves of one path.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from flycrane.model.cable_system import CableSystem
from flycrane.model.statics import evaluate_statics
from flycrane.planning.state_space import ConfigurationSpace


@dataclass(frozen=True)
class PathProfile:
    """Statics along one path at ``steps + 1`` equally spaced configurations."""

    fraction: NDArray[np.float64]  #: (S,) position along the path in [0, 1]
    tension: NDArray[np.float64]  #: (S, 6) nominal tensions f0 [N]
    tension_low: NDArray[np.float64]  #: (S, 6) t_lo [N]
    tension_high: NDArray[np.float64]  #: (S, 6) t_hi [N]
    thrust: NDArray[np.float64]  #: (S, 3) nominal thrust magnitudes |T_k| [N]
    thrust_bound: NDArray[np.float64]  #: (S, 3) worst-case thrusts m_k [N]


def configurations_at_fractions(
    path: NDArray[np.float64], space: ConfigurationSpace, fractions: NDArray[np.float64]
) -> NDArray[np.float64]:
    """Configurations at fractions of a path's length, shape (len(fractions), 9)."""
    path = np.atleast_2d(np.asarray(path, dtype=float))
    if len(path) == 1:
        return np.repeat(path, len(fractions), axis=0)
    cumulative = np.concatenate([[0.0], np.cumsum(space.distance(path[:-1], path[1:]))])
    s = np.asarray(fractions) * cumulative[-1]
    segment = np.clip(np.searchsorted(cumulative, s, side="right") - 1, 0, len(path) - 2)
    span = cumulative[segment + 1] - cumulative[segment]
    t = np.divide(s - cumulative[segment], span, out=np.zeros_like(s), where=span > 0)
    return space.interpolate(path[segment], path[segment + 1], t)


def path_profile(
    system: CableSystem, space: ConfigurationSpace, path: NDArray[np.float64], steps: int = 100
) -> PathProfile:
    """Tensions and thrusts along a path split into ``steps`` equal parts."""
    fraction = np.linspace(0.0, 1.0, steps + 1)
    configurations = configurations_at_fractions(path, space, fraction)
    report = evaluate_statics(system, configurations)
    return PathProfile(
        fraction=fraction,
        tension=report.nominal_tension,
        tension_low=report.tension_low,
        tension_high=report.tension_high,
        thrust=np.linalg.norm(report.nominal_thrust, axis=-1),
        thrust_bound=report.thrust_bound,
    )


@dataclass(frozen=True)
class LeastMargins:
    """The smallest margins of Fig. 6 along one path [N]: how close the worst cable came to
    slack (t_lo - f_lo) and to its limit (f_hi - t_hi), the worst drone to its thrust limit
    (h - m), each at the path's worst configuration."""

    slack: float
    headroom: float
    thrust: float


def least_margins(profile: PathProfile, system: CableSystem) -> LeastMargins:
    """The least margins of a path's profile (every cable, drone and sample)."""
    return LeastMargins(
        slack=float((profile.tension_low - system.tension_min).min()),
        headroom=float((system.tension_max - profile.tension_high).min()),
        thrust=float((system.max_thrusts - profile.thrust_bound).min()),
    )


def _figure():
    """A two-panel figure (tensions, thrusts). A bare Figure draws with Agg and is freed
    with its last reference: no pyplot, whose import and figure manager cost time on
    every task and which is not thread-safe."""
    from matplotlib.figure import Figure

    figure = Figure(figsize=(12, 4.5))
    return figure, figure.subplots(1, 2)


def _save(figure, out: str | Path, title: str) -> Path:
    if title:
        figure.suptitle(title, parse_math=False)  # a task name is text, not mathtext
    # Fixed margins: tight_layout draws the figure once more to measure it, for a layout
    # that these two fixed panels do not need.
    figure.subplots_adjust(left=0.06, right=0.98, bottom=0.12, top=0.86, wspace=0.18)
    out = Path(out)
    figure.savefig(out, dpi=120)
    return out


def plot_profile_bands(
    groups: Mapping[str, Sequence[PathProfile]],
    system: CableSystem,
    out: str | Path,
    title: str = "",
) -> Path:
    """Fig. 6: per planner, the band of tensions (a) and thrusts (b) over all paths; PNG."""
    figure, (tensions, thrusts) = _figure()
    colours = ["tab:red", "tab:green", "tab:blue", "tab:orange"]
    for colour, (label, profiles) in zip(colours, groups.items(), strict=False):
        if not profiles:
            continue
        x = 100 * profiles[0].fraction
        # Lowest tension any cable may reach under the perturbations (t_lo) up to the
        # highest (t_hi); nominal thrust up to the worst case (m_k): how close each planner's
        # paths come to slack cables and saturated drones.
        low = np.stack([p.tension_low for p in profiles]).min(axis=(0, 2))
        high = np.stack([p.tension_high for p in profiles]).max(axis=(0, 2))
        thrust_low = np.stack([p.thrust for p in profiles]).min(axis=(0, 2))
        thrust_high = np.stack([p.thrust_bound for p in profiles]).max(axis=(0, 2))
        label_n = f"{label} ({len(profiles)} paths)"
        tensions.fill_between(x, low, high, color=colour, alpha=0.3, label=label_n)
        thrusts.fill_between(x, thrust_low, thrust_high, color=colour, alpha=0.3, label=label_n)
    for axis, limits, name in (
        (tensions, (system.tension_min.min(), system.tension_max.max()), "cable tension [N]"),
        (thrusts, (None, system.max_thrusts.max()), "drone thrust [N]"),
    ):
        for limit in limits:
            if limit is not None:
                axis.axhline(limit, color="black", linestyle="--", linewidth=1)
        axis.set_xlabel("path step")
        axis.set_ylabel(name)
        axis.legend(loc="best")
    tensions.set_title("a) tension range")
    thrusts.set_title("b) thrust range")
    return _save(figure, out, title)


def plot_path_profile(
    profile: PathProfile, system: CableSystem, out: str | Path, title: str = ""
) -> Path:
    """One path: each cable's nominal tension and range, each drone's thrust; PNG."""
    figure, (tensions, thrusts) = _figure()
    x = 100 * profile.fraction
    for i in range(6):
        line = tensions.plot(x, profile.tension[:, i], label=f"cable {i + 1}")[0]
        tensions.fill_between(
            x,
            profile.tension_low[:, i],
            profile.tension_high[:, i],
            color=line.get_color(),
            alpha=0.12,
        )
    for k in range(3):
        line = thrusts.plot(x, profile.thrust[:, k], label=f"drone {k + 1} nominal")[0]
        thrusts.plot(
            x,
            profile.thrust_bound[:, k],
            color=line.get_color(),
            linestyle=":",
            label=f"drone {k + 1} worst case",
        )
    tensions.axhline(system.tension_min.min(), color="black", linestyle="--", linewidth=1)
    thrusts.axhline(system.max_thrusts.max(), color="black", linestyle="--", linewidth=1)
    tensions.set(xlabel="path step", ylabel="cable tension [N]", title="tensions and ranges")
    thrusts.set(xlabel="path step", ylabel="thrust [N]", title="thrusts")
    tensions.legend(fontsize=7)
    thrusts.legend(fontsize=7)
    return _save(figure, out, title)
