"""How far ArduCopter's legs stray from the plan's timing, and how far apart the three drones
drift over a flight as leg after leg adds its error.

    .venv/bin/python benchmarks/leg_drift.py sitl-seeds/*/flight

Per recorded SITL flight (``flycrane fly-sitl`` directories: ``flight.json``, the tlogs and
each simulator's DataFlash log), every timed leg's duration on each vehicle's own clock
(:func:`missions.flight_report.leg_times.flight_record`, DataFlash times) against the plan's
waypoint times (``tracks.json`` of the flown task). A drone starts each leg when it finishes the one
before, so its errors add up; the drift between drones after leg k is the spread of their
summed errors. Prints the per-leg error by kind of leg and by planned duration, and the
largest drift of each flight.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np
from bench_input import INPUT_ERRORS

from missions.flight_report.leg_times import flight_record
from missions.flight_report.record import FlightRecord
from missions.task.directory import TaskDirectory


def legs(flight_dir: Path) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A flight's legs: planned (L,) and flown (3, L) durations [s], and each drone's
    horizontal and vertical travel (3, L, 2) [m]."""
    record = flight_record(flight_dir)
    tracks = TaskDirectory(FlightRecord.read(flight_dir).task_dir).tracks()
    count = min(len(d["legs_s"]) for d in record["drones"])
    planned = np.diff(tracks.time)[:count]
    flown = np.array([d["legs_s"][:count] for d in record["drones"]])
    stored = tracks.drones_stored_enu
    step = np.diff(stored, axis=0)[:count].transpose(1, 0, 2)  # (3, L, 3)
    travel = np.stack([np.hypot(step[..., 0], step[..., 1]), step[..., 2]], axis=-1)
    return planned, flown, travel


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("flights", nargs="+", type=Path, help="fly-sitl output directories")
    args = parser.parse_args()
    errors, durations, kinds, drifts = [], [], [], []
    for flight in args.flights:
        try:
            planned, flown, travel = legs(flight)
        except INPUT_ERRORS as error:
            print(f"{flight}: skipped ({error})", file=sys.stderr)
            continue
        error = flown - planned
        errors.append(error.ravel())
        durations.append(np.broadcast_to(planned, error.shape).ravel())
        vertical = np.abs(travel[..., 1]) > 2.0 * travel[..., 0]
        kinds.append(np.where(vertical, np.where(travel[..., 1] < 0, 2, 1), 0).ravel())
        summed = np.cumsum(error, axis=1)
        drifts.append(float((summed.max(axis=0) - summed.min(axis=0)).max()))
    if not errors:
        return 2
    error, duration, kind = np.concatenate(errors), np.concatenate(durations), np.concatenate(kinds)
    print(f"{len(drifts)} flights, {len(error)} legs: flown - planned [s], median [p5, p95]")
    groups = [("all legs", np.ones_like(kind, dtype=bool))]
    groups += [(name, kind == k) for k, name in enumerate(("mostly horizontal",
               "mostly climbing", "mostly descending"))]  # fmt: skip
    groups += [(f"planned {lo}-{hi} s", (duration >= lo) & (duration < hi))
               for lo, hi in ((0, 0.5), (0.5, 1), (1, 2), (2, 5), (5, np.inf))]  # fmt: skip
    for name, mask in groups:
        if mask.any():
            e, relative = error[mask], np.abs(error[mask] / duration[mask])
            low, mid, high = np.percentile(e, [5, 50, 95])
            print(f"  {name:<20} {mask.sum():5d} legs  {mid:+.3f} [{low:+.3f}, {high:+.3f}]  "
                  f"|relative| p95 {np.percentile(relative, 95):.3f}")  # fmt: skip
    median, p90, worst = np.percentile(drifts, [50, 90, 100])
    print(f"largest drift between the drones per flight [s]: median {median:.3f}, p90 "
          f"{p90:.3f}, max {worst:.3f}")  # fmt: skip
    return 0


if __name__ == "__main__":
    sys.exit(main())
