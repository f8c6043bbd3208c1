"""The flight report at a glance: one figure, four panels against mission time, the verdict
in the title."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from missions.flight_report.report import FlightReport

#: Colours of the two position sources.
SOURCES = {"estimated": "tab:blue", "true": "tab:red"}


def plot_flight_report(report: FlightReport, out: Path, title: str = "") -> Path:
    """Timing, inter-drone distance error, statics margins and obstacle clearance; PNG."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    t = np.array(report.series["time"]["mission"])
    figure, axes = plt.subplots(2, 2, figsize=(13, 8), sharex=True)
    progress = np.array(report.series["progress"]["plan_time"], dtype=float)
    ax = axes[0, 0]
    for k in range(3):
        ax.plot(t, progress[:, k] - t, label=f"drone {k + 1}")
    tolerance = report.start_offset_tolerance
    ax.axhspan(-tolerance, tolerance, color="tab:green", alpha=0.1, label="claimed tolerance")
    ax.set_ylabel("progress - mission time [s]")
    ax.set_title(
        f"timing: flown {report.timing.flown_duration:.2f} s of {report.planned_duration:.2f} s, "
        f"release spread {report.release_spread * 1000:.0f} ms",
        fontsize=10,
    )
    ax.legend(fontsize=8)
    for source, figures in (("estimated", report.estimated), ("true", report.true)):
        if figures is None:
            continue
        series = report.series[source]
        colour = SOURCES[source]
        axes[0, 1].plot(t, series["inter_drone_error"], color=colour,
                        label=f"{source} (p95 {figures.inter_drone_error_p95:.3f} m)")  # fmt: skip
        axes[1, 0].plot(t, series["slack_margin"], color=colour, label=f"{source} slack")
        axes[1, 0].plot(t, series["thrust_margin"], color=colour, linestyle="--",
                        label=f"{source} thrust")  # fmt: skip
        axes[1, 1].plot(t, series["clearance"], color=colour,
                        label=f"{source} (least {figures.least_clearance:.3f} m)")  # fmt: skip
    axes[0, 1].set_ylabel("inter-drone distance error [m]")
    axes[0, 1].set_title("the three drones against each other", fontsize=10)
    axes[1, 0].axhline(0.0, color="k", linewidth=0.8)
    axes[1, 0].set_ylabel("least margin [N]")
    axes[1, 0].set_title("statics of the load rebuilt from the drones", fontsize=10)
    axes[1, 1].axhline(0.0, color="k", linewidth=0.8)
    axes[1, 1].set_ylabel("clearance to the real obstacles [m]")
    axes[1, 1].set_title("collisions (negative: penetration)", fontsize=10)
    for ax in axes.flat:
        ax.grid(alpha=0.3)
    for ax in axes[1]:
        ax.set_xlabel("mission time [s]")
    for ax in (axes[0, 1], axes[1, 0], axes[1, 1]):
        ax.legend(fontsize=8)
    verdict = str(report.verdict)
    figure.suptitle(f"{title}\n{verdict}" if title else verdict, fontsize=11)
    figure.tight_layout()
    figure.savefig(out, dpi=110)
    plt.close(figure)
    return out
