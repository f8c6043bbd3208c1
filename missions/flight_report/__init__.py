"""Flight reports: how a recorded flight went against its plan, and whether it was safe.

- :mod:`.vehicle_log` reads one drone's tlog (estimate, truth where a simulator gives it,
  events);
- :mod:`.alignment` puts the three drones on one mission time;
- :mod:`.planned_flight` reads what the drones were told (a task's directory);
- :mod:`.timing` says when each drone started, arrived and where it was along the plan;
- :mod:`.report` computes every figure and the verdict, :mod:`.plot` draws them and
  :mod:`.flight_mcap` logs them for Foxglove.

:func:`report_sitl_flight` reports a flight our SITL harness recorded (its directory has
``flight.json``), :func:`report_tlogs` any three tlogs of a task's missions (a real flight
recorded by a ground station); :func:`write_report` saves ``report.json``, ``report.png``,
``flown.json`` (the viewer draws the flown path from it, ``docs/viewer.md``) and
``flight.mcap`` (the same figures over time, for Foxglove).
"""

from __future__ import annotations

import itertools
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from flycrane.errors import FieldProblem, InputError
from missions.execution.record import ExecutionRecord
from missions.export.formats import dumps, finite
from missions.flight_report.alignment import (
    AlignmentError,
    Releases,
    releases_from_logs,
    releases_on_common_clock,
)
from missions.flight_report.flight_mcap import write_flight_mcap
from missions.flight_report.planned_flight import PlannedFlight
from missions.flight_report.plot import plot_flight_report
from missions.flight_report.record import (
    EXECUTION_FILE,
    FLOWN_FILE,
    MCAP_FILE,
    PLOT_FILE,
    REPORT_FILE,
    FlightRecord,
)
from missions.flight_report.report import FlightReport, flight_report
from missions.flight_report.timing import flown_at
from missions.flight_report.vehicle_log import VehicleLog, read_vehicle_log
from missions.task.directory import TaskDirectory

#: How much better another order of the logs must fit the formation to be refused.
ORDER_FIT = 3.0


@dataclass(frozen=True)
class SitlFlight:
    """A SITL flight as read back: its record, what the drones were told, their logs, and
    mission time on the simulators' common clock."""

    flight: FlightRecord
    record: ExecutionRecord
    #: the plan as the drones were given it (``stream``, ``onboard``: on the group clock)
    plan: PlannedFlight
    vehicles: list[VehicleLog]
    releases: Releases
    start: float  #: common time of mission time 0 [s]


def read_sitl_flight(flight_dir: Path) -> SitlFlight:
    """A flight our SITL harness recorded, on the simulators' common clock: from the first
    release (``missions``), or from the executor's plan start (``stream``, ``onboard``),
    whose clock also times the plan the drones were given.

    Raises
    ------
    InputError, TaskDirectoryError, AlignmentError
        A file the report needs is missing or unreadable.
    """
    flight = FlightRecord.read(flight_dir)
    plan = PlannedFlight.read(Path(flight.task_dir))
    origin = plan.task.mission.origin
    height = plan.task.mission.home_height
    vehicles = [
        read_vehicle_log(flight_dir / v.tlog, v.name, origin, height) for v in flight.vehicles
    ]
    record = ExecutionRecord.read(flight_dir / EXECUTION_FILE)
    if flight.mode == "missions":
        releases = releases_on_common_clock(vehicles, release_seq=flight.release_seq)
        first = vehicles[0]
        start = releases.vehicle_time[0] + (first.clock_offset or 0.0) - releases.common_time[0]
    else:
        releases = releases_on_common_clock(vehicles, start=record.start)
        start = record.start
        ends = [releases.mission_time(k, v.estimated.time[-1:])[0] for k, v in enumerate(vehicles)]
        last = min(ends)
        if last <= 0.0:  # a team stop before the plan's clock ran, and no log after it
            name = vehicles[ends.index(last)].name
            raise AlignmentError(
                f"{name}: its log ends {-last:.2f} s before the plan's start: no flight to judge"
            )
        trajectory = TaskDirectory(Path(flight.task_dir)).trajectory()
        plan = plan.executed(trajectory, record.clock(), flight.mode, float(last))
    return SitlFlight(flight, record, plan, vehicles, releases, start)


def report_sitl_flight(flight_dir: Path) -> tuple[FlightReport, PlannedFlight]:
    """The report of a SITL flight (:func:`read_sitl_flight`).

    Raises
    ------
    InputError, TaskDirectoryError, AlignmentError
        A file the report needs is missing or unreadable.
    """
    read = read_sitl_flight(flight_dir)
    flight, record, plan, start = read.flight, read.record, read.plan, read.start
    vehicles, releases = read.vehicles, read.releases
    stop = None
    if record.commanded_stop_at is not None:
        struck = [f["time"] for f in flight.faults if f["kind"] not in ("late", "operator")]
        stop = (record.commanded_stop_at - start, min(struck) - start if struck else None)
    # after a retreat the whole flight is judged; after a stop and a hold, through the hold
    retreated = any(f.get("action") == "retreat" for f in flight.faults)
    report = flight_report(
        plan, vehicles, releases, flight.parameter_differences, stop, judge_all=retreated
    )
    return report, plan


def report_tlogs(task_dir: Path, tlogs: Sequence[Path]) -> tuple[FlightReport, PlannedFlight]:
    """The report of three drones' tlogs (drone 1, 2, 3) of the missions in ``task_dir``:
    releases from the logs alone."""
    plan = PlannedFlight.read(task_dir)
    origin = plan.task.mission.origin
    height = plan.task.mission.home_height
    vehicles = [
        read_vehicle_log(path, f"drone{k + 1}", origin, height) for k, path in enumerate(tlogs)
    ]
    _distinct(tlogs)
    try:
        releases = releases_on_common_clock(vehicles, release_seq=plan.release.release_seq)
    except AlignmentError:  # no SYSTEM_TIME in the logs
        releases = releases_from_logs(vehicles, plan.release.release_seq)
    _in_order(plan, vehicles, releases)
    return flight_report(plan, vehicles, releases), plan


def _distinct(tlogs: Sequence[Path]) -> None:
    """Refuses one log given for two drones (their sizes and first megabyte equal)."""
    heads = []
    for path in tlogs:
        with path.open("rb") as file:
            heads.append((path.stat().st_size, file.read(1 << 20)))
    for i, j in itertools.combinations(range(len(tlogs)), 2):
        if heads[i] == heads[j]:
            raise InputError([FieldProblem("tlogs", (
                f"{tlogs[i]} and {tlogs[j]} are one log: give drone 1, 2 and 3's"))])  # fmt: skip


def _in_order(plan: PlannedFlight, vehicles: Sequence[VehicleLog], releases: Releases) -> None:
    """Refuses logs given in another order than drone 1, 2, 3: at the release the drones
    hold the plan's formation, whatever common offset their positions have, and another
    order of the logs fits it at least :data:`ORDER_FIT` times better."""
    held = flown_at([v.estimated for v in vehicles], releases, np.zeros(1))[0]
    planned = plan.drones_at(np.zeros(1))[0]

    def misfit(order: tuple[int, ...]) -> float:
        drones = held[list(order)]
        shape = (drones - drones.mean(axis=0)) - (planned - planned.mean(axis=0))
        return float(np.linalg.norm(shape, axis=-1).max())

    given = tuple(range(len(vehicles)))
    best = min(itertools.permutations(given), key=misfit)
    if best != given and misfit(best) * ORDER_FIT < misfit(given):
        order = ", ".join(f"{'1st 2nd 3rd'.split()[k]}" for k in best)
        raise InputError([FieldProblem("tlogs", (
            f"at the release the logs hold the formation {misfit(given):.2f} m from the "
            f"plan's, the {order} given {misfit(best):.2f} m: give drone 1, 2 and 3's logs, "
            "in that order"))])  # fmt: skip


def write_report(
    report: FlightReport, plan: PlannedFlight, out_dir: Path, title: str = ""
) -> dict[str, Path]:
    """``report.json``, ``report.png``, ``flown.json`` (the safety source's drones on
    mission time, for the viewer) and ``flight.mcap`` (:mod:`.flight_mcap`) into
    ``out_dir``."""
    out_dir.mkdir(parents=True, exist_ok=True)
    (out_dir / REPORT_FILE).write_text(dumps(report.as_dict()), encoding="utf-8")
    plot_flight_report(report, out_dir / PLOT_FILE, title)
    source = "true" if report.true is not None else "estimated"
    flown: dict[str, Any] = {
        "source": f"flight-{source}",
        "time": report.series["time"]["mission"],
        "drones_enu": report.series[source]["drones_enu"],
    }
    (out_dir / FLOWN_FILE).write_text(dumps(finite(flown)), encoding="utf-8")
    write_flight_mcap(report, plan, out_dir / MCAP_FILE)
    return {name: out_dir / name for name in (REPORT_FILE, PLOT_FILE, FLOWN_FILE, MCAP_FILE)}
