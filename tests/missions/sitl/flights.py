"""What the SITL tests share: the marks that skip them without SITL or a private network,
planning a task for them, and flying it with ``flycrane fly-sitl`` in a subprocess (every
simulator checked gone by its PID afterwards)."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from flycrane.planning.planners import PlannerOptions
from missions.options import MissionOptions
from missions.sitl.netns import namespaces_available
from missions.sitl.process import alive
from missions.sitl.settings import SitlSettings
from missions.task.pipeline import run_task
from missions.task.spec import TaskSpec

SETTINGS = SitlSettings()
NAMESPACES = namespaces_available()
SITL_MARKS = [
    pytest.mark.sitl,
    pytest.mark.skipif(
        not SETTINGS.binary.is_file(),
        reason=f"no ArduCopter SITL at {SETTINGS.binary} (set FLYCRANE_SITL_BINARY)",
    ),
    pytest.mark.skipif(NAMESPACES is not None, reason=f"no private network: {NAMESPACES}"),
]
#: A flight takes about 25 s of wall time at x5; the bound is for a machine under load.
FLIGHT_TIMEOUT_S = 600
#: The simulators' speed-up in the tests. The ground's pauses count this many times over in
#: the drones' time: at x10, a 50 ms pause of this machine (2 cores, three simulators and
#: the ground) is half a second of the drones' time, which starves GUIDED of targets and
#: reads as a lost link, so x10 judges the load of the machine, not the execution. At x5 it
#: is a quarter of a second (BENCHMARKS.md "Execution in step").
SPEEDUP = 5
#: The speed-up of the flights whose verdict turns on the ground's timing within a tenth of
#: a second of the drones' time: every stream and onboard flight but the stock sensors'
#: (starts, progress, a team stop and its drones at rest, a weak motor's followers). At x5
#: a 20-70 ms pause of the ground (a reader waiting for Python's lock, a simulator waiting
#: for a core) is 0.1-0.35 s of the drones' time: the Puzzle's seed-5 weak motor lost its
#: load in 3 of 4 such flights, the Rescue in step once started 0.14 s apart, and each of
#: these tests failed in one of four suite runs or more at x5 (BENCHMARKS.md "The suite's
#: flights that judge tenths of a second", "The suite's run time").
CLOSE_SPEEDUP = 2
#: Every flight boots, takes off and settles at its hold at x10, where nothing turns on the
#: ground's tenths of a second (the harness asks for the telemetry at a rate the ground
#: reads as fast as the flight's), and is then played at its own speed-up
#: (``--boot-speedup``), its three clocks brought together before the release. Faster, three
#: simulators outrun this machine's two cores (BENCHMARKS.md "The recorded estimates, a
#: faster boot and the simulators' clocks").
BOOT_SPEEDUP = 10


def plan(scene: str, seed: int, out: Path, robust_clearance: bool = True) -> Path:
    task = TaskSpec(
        scene=scene,
        planner=PlannerOptions(seed=seed, time_budget=120),
        mission=MissionOptions(position_error="sitl", robust_clearance=robust_clearance),
    )
    outcome = run_task(task, out)
    assert outcome.status == "done", outcome.reason
    return out


def run_fly_sitl(
    task_dir: Path,
    out: Path,
    *extra: str,
    env: dict[str, str] | None = None,
    speedup: float = SPEEDUP,
) -> subprocess.CompletedProcess:
    """``flycrane fly-sitl`` in a subprocess at ``speedup`` after a boot at
    :data:`BOOT_SPEEDUP`, given paths relative to its
    working directory as a user types them (SITL runs in directories of its own); every
    simulator checked gone afterwards."""
    cwd = Path(os.path.commonpath([task_dir, out]))
    command = [sys.executable, "-m", "flycrane.cli", "fly-sitl", os.path.relpath(task_dir, cwd),
               "--out", os.path.relpath(out, cwd), "--speedup", str(speedup),
               "--boot-speedup", str(BOOT_SPEEDUP), *extra]  # fmt: skip
    done = subprocess.run(command, capture_output=True, text=True, timeout=FLIGHT_TIMEOUT_S,
                          cwd=cwd, env={**os.environ, **(env or {})})  # fmt: skip
    started = out / "sitl" / "pids.json"  # written once the simulators started
    pids = json.loads(started.read_text()) if started.exists() else []
    assert not [pid for pid in pids if alive(pid)], "a simulator outlived its flight"
    return done


def stalled(out: Path, extra: tuple[str, ...]) -> bool:
    """Whether the flight in ``out`` stopped on a drone's silence that no injected link
    fault explains: a simulator that paused on this host, not a drone (at x5, 0.1 s of
    this machine is the 0.5 s of silence that stops the team; 8 such stops in 40 flights
    of BENCHMARKS.md "A lost link in real time")."""
    record_file = out / "execution.json"
    if not record_file.exists():
        return False
    record = json.loads(record_file.read_text())
    faults = [extra[i + 1] for i, word in enumerate(extra[:-1]) if word == "--fault"]
    cut = [(int(f.split(":")[1]), float(f.split(":")[2])) for f in faults if f[:5] == "link:"]
    start = record["start"]  # None: stopped before the plan's clock existed

    def explained(fault: dict) -> bool:
        return start is not None and any(
            drone == fault["drone"] and fault["time"] - start >= at - 0.1 for drone, at in cut
        )

    return any(fault["kind"] == "link" and not explained(fault) for fault in record["faults"])


def fly(task_dir: Path, out: Path, *extra: str, speedup: float = SPEEDUP) -> dict:
    """Fly on SITL at ``speedup`` and return report.json (the flight was released: safe or
    not). A flight that :func:`stalled` is flown once more, the first kept beside ``out``."""
    done = run_fly_sitl(task_dir, out, *extra, speedup=speedup)
    if stalled(out, extra):
        out.rename(out.with_name(out.name + "-stalled"))
        out.mkdir()
        done = run_fly_sitl(task_dir, out, *extra, speedup=speedup)
    assert done.returncode in (0, 1), done.stderr[-3000:]  # 0 safe, 1 unsafe
    report = json.loads((out / "report.json").read_text())
    assert (done.returncode == 0) == report["verdict"]["safe"]
    return report
