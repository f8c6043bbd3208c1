"""The platform's error bound (flycrane/model/pose_error.py) along planned paths and
against the errors flown on ArduCopter SITL.

    .venv/bin/python benchmarks/pose_error_bound.py FLIGHT_DIR... [--model sitl]

Each FLIGHT_DIR is a ``flycrane fly-sitl --mode stream`` output (execution.json and
report.json) whose task directory is ``FLIGHT_DIR/../plan`` (the layout of
benchmarks/execution_modes.py). Per flight, at every sample of the report (10 Hz, true
positions): the planned configuration (the drones' trajectories at the group clock's plan
time, solved by the direct kinematics), the flown one (the report's, rebuilt from SIM_STATE),
how far each payload corner moved between them, and the bound the position-error model
gives at the planned configuration (common part, and each drone's own part as two thirds
of the model's relative bound: three errors pairwise within r are each within 2r/3 of
their mean). Prints the bound's least, median and largest value against the fixed
clearance the plan keeps, the flown displacement's median and largest, and how many
samples the bound covers. BENCHMARKS.md ("Planner v3", "Robust margins") records the runs.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

from flycrane.model.cable_system import CableSystem
from flycrane.model.direct_kinematics import configuration_from_drone_positions
from flycrane.model.kinematics import matrix_from_tilt_torsion
from flycrane.model.pose_error import displacement_bound
from flycrane.world.scene import Box
from missions.execution.record import ExecutionRecord
from missions.position_error import PRESETS
from missions.task.directory import TaskDirectory


def payload_points(task_dir: Path) -> np.ndarray:
    """Corners of the payload's boxes and the other shapes' centres, platform frame."""
    scene = TaskDirectory(task_dir).task().scene
    points = []
    for shape in scene.payload.shapes:
        centre = np.array(shape.center)
        if isinstance(shape, Box):
            rotation = matrix_from_tilt_torsion(np.array(shape.rotation))
            signs = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)])
            points += list(centre + (signs * np.array(shape.size) / 2) @ rotation.T)
        else:
            points.append(centre)
    return np.array(points)


def measure(flight: Path, model_name: str) -> dict:
    task_dir = flight.parent / "plan"
    directory = TaskDirectory(task_dir)
    task = directory.task()
    system = CableSystem.from_spec(task.system)  # type: ignore[arg-type]
    record = ExecutionRecord.read(flight / "execution.json")
    clock = record.clock()
    report = json.loads((flight / "report.json").read_text())
    series = report["series"]
    time = np.array(series["time"]["mission"])
    flown = np.array(series["true"]["configurations"])
    trajectory = directory.trajectory()
    tau = np.array([clock.tau(clock.start + t) for t in time])
    drones = trajectory.in_task_frame(trajectory.at(tau)[0])
    planned = configuration_from_drone_positions(system, drones, initial=flown).q
    points = payload_points(task_dir)
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


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("flights", nargs="+", type=Path)
    parser.add_argument("--model", default="sitl", choices=sorted(PRESETS))
    args = parser.parse_args()
    rows = [measure(flight, args.model) for flight in args.flights]
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
