"""How each drone of a stream or onboard SITL flight followed its trajectory: its lag and
its steady offset, horizontally and vertically.

    .venv/bin/python benchmarks/tracking_lag.py FLIGHT_DIR...

Each FLIGHT_DIR is a ``flycrane fly-sitl --mode stream|onboard`` output. Per drone, from the
autopilot's estimates on the common clock (the flight report's reading,
:func:`missions.flight_report.read_sitl_flight`) against the plan as given on the group
clock, between 0.2 s after the start and 0.2 s before the end: the lag [ms] that best lays
the flown track over the plan (least squares over shifts of 5 ms, east-north and up
apart; negative: ahead), with ``--offsets`` each shift's mean offset taken out first (a
steady offset along the motion otherwise reads as lag), the median offset [cm] (east,
north, up), and the p95 distance [cm] as flown and with the lags taken out. A lag that
removing changes the p95 little is not what the error is made of. BENCHMARKS.md
("Execution in step", "Second run") records the runs that set the executors' leads.
"""

from __future__ import annotations

import argparse
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from bench_input import exit_if_unreadable
from numpy.typing import NDArray

from missions.flight_report import read_sitl_flight

SHIFTS = np.arange(-0.2, 0.4 + 1e-9, 0.005)
EDGE_S = 0.2
AXES = {"horizontal": [0, 1], "vertical": [2]}


@dataclass(frozen=True)
class DroneFigures:
    lag: dict[str, float]  #: [s] per axis group; negative: ahead
    offset: NDArray[np.float64]  #: median (east, north, up) [m]
    p95: float  #: [m]
    p95_without_lag: float  #: [m]


def drone_figures(flight_dir: Path, offsets: bool = False) -> list[DroneFigures]:
    """Each drone's lags, offset and p95 distances (module docstring)."""
    read = read_sitl_flight(flight_dir)
    plan, figures = read.plan, []
    for k, vehicle in enumerate(read.vehicles):
        series = vehicle.estimated
        t = read.releases.mission_time(k, series.time)
        kept = (t > EDGE_S) & (t < plan.duration - EDGE_S)
        t, flown = t[kept], series.enu[kept]
        lags, unlagged = {}, plan.drones_at(t)[:, k].copy()
        for name, axes in AXES.items():
            costs = []
            for shift in SHIFTS:
                error = flown[:, axes] - plan.drones_at(t - shift)[:, k][:, axes]
                if offsets:
                    error = error - error.mean(axis=0)
                costs.append(np.sum(error**2))
            lags[name] = float(SHIFTS[int(np.argmin(costs))])
            unlagged[:, axes] = plan.drones_at(t - lags[name])[:, k][:, axes]
        error = flown - plan.drones_at(t)[:, k]
        figures.append(
            DroneFigures(
                lag=lags,
                offset=np.median(error, axis=0),
                p95=float(np.percentile(np.linalg.norm(error, axis=1), 95)),
                p95_without_lag=float(np.percentile(np.linalg.norm(flown - unlagged, axis=1), 95)),
            )
        )
    return figures


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("flights", nargs="+", type=Path)
    parser.add_argument("--offsets", action="store_true", help="fit each lag with an offset")
    args = parser.parse_args()
    header = "flight | drone | lag h, v [ms] | offset e, n, u [cm] | p95 [cm] | p95 lag out [cm]"
    for flight_dir in args.flights:
        with exit_if_unreadable(parser, flight_dir):
            figures = drone_figures(flight_dir, args.offsets)
        if header:  # once a flight has been read: a bad first one prints only its error
            print(header)
            header = ""
        for k, f in enumerate(figures):
            offset = ", ".join(f"{x * 100:+.1f}" for x in f.offset)
            print(
                f"{flight_dir} | {k + 1} | {f.lag['horizontal'] * 1000:.0f}, "
                f"{f.lag['vertical'] * 1000:.0f} | {offset} | {f.p95 * 100:.2f} | "
                f"{f.p95_without_lag * 100:.2f}"
            )


if __name__ == "__main__":
    main()
