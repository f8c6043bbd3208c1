"""The platform's error bound (flycrane/model/pose_error.py) along planned paths and
against the errors flown on ArduCopter SITL.

    .venv/bin/python benchmarks/pose_error_bound.py FLIGHT_DIR... [--model sitl]

Each FLIGHT_DIR is a ``flycrane fly-sitl --mode stream`` output (execution.json and
report.json); its task directory is the one its flight.json names. Per flight, at every
sample of the report (10 Hz, true positions): the planned configuration (the drones'
trajectories at the group clock's plan time, solved by the direct kinematics), the flown one
(the report's, rebuilt from SIM_STATE), how far each payload corner moved between them, and
the bound the position-error model gives at the planned configuration (common part, and each
drone's own part as two thirds of the model's relative bound: three errors pairwise within r
are each within 2r/3 of their mean). Prints the bound's least, median and largest value
against the fixed clearance the plan keeps, the flown displacement's median and largest, and
how many samples the bound covers.

With ``--near D``, the bound on how far the drones' errors can close the gap to the
nearest obstacle instead, at the samples whose planned configuration is within D [m] of
one (real obstacles, no clearance): the bound of :class:`flycrane.planning.
robust_clearance.RobustClearance`, against the fixed clearance and the gap the flight lost
there.

With ``--statics``, the bound on how far the drones' own errors can lower each tension and
thrust margin (:mod:`flycrane.model.robust_statics`) at every sample, against how far the
flown configuration's margins fell below the planned one's. BENCHMARKS.md ("Planner v3",
"Robust margins", "Robust statics margins") records the runs.
"""

from __future__ import annotations

import argparse
import json
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import numpy as np
from bench_input import exit_if_unreadable

from flycrane.model.cable_system import CableSystem
from flycrane.model.direct_kinematics import configuration_from_drone_positions
from flycrane.model.kinematics import matrix_from_tilt_torsion
from flycrane.model.pose_error import displacement_bound
from flycrane.model.robust_statics import RobustStatics, margins
from flycrane.model.statics import evaluate_statics
from flycrane.planning.problem import PlanningProblem
from flycrane.planning.robust_clearance import RobustClearance
from flycrane.world.bodies import box_corners, payload_bodies
from flycrane.world.scene import Box
from missions.execution.record import ExecutionRecord
from missions.flight_report.record import FlightRecord
from missions.position_error import PRESETS
from missions.task.directory import TaskDirectory


def task_directory(flight: Path) -> TaskDirectory:
    """The task the flight flew: the directory its flight.json names."""
    return TaskDirectory(FlightRecord.read(flight).task_dir)


def payload_points(task_dir: Path) -> np.ndarray:
    """Corners of the payload's boxes and the other shapes' centres, platform frame."""
    scene = TaskDirectory(task_dir).task().scene
    bodies = payload_bodies(scene, task_dir)  # type: ignore[arg-type]
    points = [
        box_corners(body) if isinstance(shape, Box) else np.array([shape.center])
        for shape, body in zip(scene.payload.shapes, bodies, strict=True)  # type: ignore[union-attr]
    ]
    return np.concatenate(points)


def planned_and_flown(flight: Path) -> tuple[CableSystem, np.ndarray, np.ndarray, np.ndarray]:
    """The system, the report's times, and at each the planned configuration (the drones'
    trajectories at the group clock's plan time, by the direct kinematics) and the flown
    one (the report's, from SIM_STATE)."""
    directory = task_directory(flight)
    system = CableSystem.from_spec(directory.task().system)  # type: ignore[arg-type]
    clock = ExecutionRecord.read(flight / "execution.json").clock()
    series = json.loads((flight / "report.json").read_text())["series"]
    time = np.array(series["time"]["mission"])
    flown = np.array(series["true"]["configurations"], dtype=float)
    trajectory = directory.trajectory()
    tau = np.array([clock.tau(clock.start + t) for t in time])
    drones = trajectory.in_task_frame(trajectory.at(tau)[0])
    planned = configuration_from_drone_positions(system, drones, initial=flown).q
    return system, time, planned, flown


def measure(flight: Path, model_name: str) -> dict:
    system, _, planned, flown = planned_and_flown(flight)
    points = payload_points(task_directory(flight).path)
    rotation = matrix_from_tilt_torsion(planned[:, 3:6])
    planned_points = planned[:, None, :3] + np.einsum("nab,pb->npa", rotation, points)
    rotation = matrix_from_tilt_torsion(flown[:, 3:6])
    flown_points = flown[:, None, :3] + np.einsum("nab,pb->npa", rotation, points)
    displacement = np.linalg.norm(flown_points - planned_points, axis=-1).max(axis=1)
    model = PRESETS[model_name]
    common = (model.common_horizontal, model.common_vertical)
    bound = displacement_bound(system, planned, points, common, model.own).max(axis=1)
    keep = np.isfinite(displacement) & np.isfinite(bound)
    return {
        "flight": str(flight),
        "samples": int(keep.sum()),
        "bound": np.percentile(bound[keep], [0, 50, 100]),
        "flown": np.percentile(displacement[keep], [50, 100]),
        "covered": float(np.mean(displacement[keep] <= bound[keep])),
        "clearance": model.obstacle_clearance,
    }


def measure_near(flight: Path, model_name: str, near: float) -> dict:
    """The bound along the nearest obstacle's direction at the samples within ``near``
    (:class:`~flycrane.planning.robust_clearance.RobustClearance`)."""
    task = task_directory(flight).task()  # self-contained: specs written out
    real = PlanningProblem.from_scene(task.scene, task.system).validity.with_clearance(0.0)  # type: ignore[arg-type]
    _, _, planned, flown = planned_and_flown(flight)
    model = PRESETS[model_name]
    common = (model.common_horizontal, model.common_vertical)
    robust = RobustClearance(real, common, model.own, near=near)
    keep = np.isfinite(planned).all(axis=1)
    gap, bound = robust.gaps(planned[keep])
    close = gap <= near
    gap, bound, flown = gap[close], bound[close], flown[keep][close]
    lost = gap - np.array([real.collision.clearance(q) for q in flown])
    return {
        "flight": str(flight),
        "samples": int(close.sum()),
        "bound": np.percentile(bound, [0, 50, 100]),
        "at_least_gap": bound[np.argmin(gap)],
        "lost": lost.max(),
        "covered": float(np.mean(lost <= bound)),
        "clearance": model.obstacle_clearance,
    }


def measure_statics(flight: Path, model_name: str) -> dict:
    """Each margin's fall from the planned to the flown configuration against its bound."""
    system, _, planned, flown = planned_and_flown(flight)
    keep = np.isfinite(planned).all(axis=1) & np.isfinite(flown).all(axis=1)
    robust = RobustStatics.of(system, planned[keep], PRESETS[model_name].own)
    fall = robust.margin - margins(evaluate_statics(system, flown[keep]))
    bounded = np.isfinite(robust.bound) & np.isfinite(fall)
    return {
        "flight": str(flight),
        "samples": int(keep.sum()),
        "bound": np.percentile(robust.bound[bounded], [50, 100]),
        "fall": np.percentile(fall[bounded], [50, 100]),
        "ratio": float(np.max(fall[bounded] / robust.bound[bounded])),
        "covered": float(np.mean(fall[bounded] <= robust.bound[bounded])),
        "planned_least": float(robust.margin.min()),
        "robust_least": robust.least()[0],
        "flown_least": float((robust.margin - fall)[bounded].min()),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("flights", nargs="+", type=Path)
    parser.add_argument("--model", default="sitl", choices=sorted(PRESETS))
    parser.add_argument("--near", type=float, help="[m] the nearest obstacle's direction")
    parser.add_argument("--statics", action="store_true", help="the margins' bound instead")
    args = parser.parse_args()

    def each(measure: Callable[..., dict], *options: Any) -> Iterator[dict]:
        """``measure`` of each flight; a flight that cannot be read ends the run (exit 2)."""
        for flight in args.flights:
            with exit_if_unreadable(parser, flight):
                row = measure(flight, *options)
            yield row

    if args.statics:
        print("flight: samples | bound median/max N | fall median/max N | worst fall/bound | "
              "covered | least margin planned/robust/flown N")  # fmt: skip
        for r in each(measure_statics, args.model):
            b, f = r["bound"], r["fall"]
            print(
                f"{r['flight']}: {r['samples']} | {b[0]:.3f}/{b[1]:.3f} | {f[0]:.3f}/{f[1]:.3f}"
                f" | {r['ratio']:.2f} | {r['covered']:.1%} | {r['planned_least']:.2f}/"
                f"{r['robust_least']:.2f}/{r['flown_least']:.2f}"
            )
        return
    if args.near is not None:
        print("flight: samples | bound min/median/max cm | at the least gap | lost max | covered")
        for r in each(measure_near, args.model, args.near):
            b = r["bound"] * 100
            print(
                f"{r['flight']}: {r['samples']} | {b[0]:.1f}/{b[1]:.1f}/{b[2]:.1f} | "
                f"{100 * r['at_least_gap']:.1f} | {100 * r['lost']:.1f} | {r['covered']:.0%}"
            )
        return
    rows = list(each(measure, args.model))
    print("flight: samples | bound min/median/max cm | flown median/max cm | covered | fixed cm")
    for r in rows:
        b, f = r["bound"] * 100, r["flown"] * 100
        print(
            f"{r['flight']}: {r['samples']} | {b[0]:.1f}/{b[1]:.1f}/{b[2]:.1f} | "
            f"{f[0]:.1f}/{f[1]:.1f} | {r['covered']:.1%} | {100 * r['clearance']:.1f}"
        )
    bounds = np.concatenate([r["bound"] for r in rows]) * 100
    flown = np.array([r["flown"][1] for r in rows]) * 100
    covered = np.mean([r["covered"] for r in rows])
    print(
        f"all {len(rows)} flights: bound {bounds.min():.1f}-{bounds.max():.1f} cm, largest flown "
        f"displacement {flown.max():.1f} cm, samples covered {covered:.1%}"
    )


if __name__ == "__main__":
    main()
