"""What building and writing a mission costs as its duration grows, up to the longest one
the service accepts (``missions.options.MAX_MISSION_DURATION_S``).

    .venv/bin/python benchmarks/mission_bounds.py --lengths 30 75 150 270

Each run plans nothing: an open field, the platform 3 m up, a straight path of LENGTH m at
the default 0.5 m/s (about LENGTH / 0.5 s of mission). It prints, per length, the mission's
duration, the wall time and the Python peak memory (tracemalloc) of building the missions
and of writing every artifact, and the size of tracks.json. BENCHMARKS.md ("Bounded work")
records the runs.
"""

from __future__ import annotations

import argparse
import tempfile
import time
import tracemalloc

import numpy as np

from flycrane.planning.planners import plan
from missions.task.build import build
from missions.task.directory import TRACKS_FILE, TaskDirectory
from missions.task.limits import MissionFailure
from missions.task.resolve import resolve_task
from missions.task.spec import TaskSpec
from missions.task.write import write_files

LEVEL = [0.0, 0.0, 0.0, 1.0, 1.0, 1.0]


def field_task(length: float) -> TaskSpec:
    scene = {
        "name": "field",
        "ground": True,
        "obstacles": [],
        "bounds": {"position_low": [-10, -50, 0], "position_high": [length + 10, 50, 20]},
        "start": [0.0, 0.0, 3.0, *LEVEL],
        "goal": [length, 0.0, 3.0, *LEVEL],
    }
    return TaskSpec.model_validate({"scene": scene, "mission": {"position_error": "exact"}})


def measure(length: float) -> str:
    resolved = resolve_task(field_task(length))
    planned = plan(
        resolved.problem.space,
        resolved.checkers.planning,
        resolved.start,
        resolved.goal,
        resolved.task.planner.model_copy(update={"smoothing_attempts": 0}),
        algorithm="rrt",
    )
    tracemalloc.start()
    clock = time.perf_counter()
    try:
        built = build(resolved, planned.path)
    except MissionFailure as failure:
        tracemalloc.stop()
        return f"{length:7.0f} m: {failure}"
    build_time = time.perf_counter() - clock
    _, build_peak = tracemalloc.get_traced_memory()
    tracemalloc.reset_peak()
    with tempfile.TemporaryDirectory() as scratch:
        directory = TaskDirectory(scratch).create()
        clock = time.perf_counter()
        write_files(directory, resolved, planned, built)
        write_time = time.perf_counter() - clock
        _, write_peak = tracemalloc.get_traced_memory()
        # write_files leaves the files staged (.partial/): only the run's summary moves them
        tracks = directory.file(TRACKS_FILE).stat().st_size
    tracemalloc.stop()
    return (
        f"{length:7.0f} m {built.summary.duration:7.0f} s | build {build_time:6.1f} s "
        f"{build_peak / 1e6:7.1f} MB | write {write_time:6.1f} s {write_peak / 1e6:7.1f} MB | "
        f"tracks.json {tracks / 1e6:6.1f} MB"
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--lengths", nargs="+", type=float, default=[30, 75, 150, 270])
    args = parser.parse_args()
    print("length duration | build time, peak | write time, peak | tracks.json")
    for length in np.asarray(args.lengths):
        print(measure(float(length)), flush=True)


if __name__ == "__main__":
    main()
