"""How long each timed leg of a flown spline mission took, from the vehicle's own logs.

A timed leg k runs from waypoint k - 1 to waypoint k, the k-th NAV_SPLINE_WAYPOINT of the
mission (:mod:`missions.export.builder`). Per drone, on the vehicle's own clock:

- leg 1 starts at the release: the item the ground station's MISSION_SET_CURRENT named
  starts (ArduCopter starts it at once);
- leg k > 1 starts when waypoint k starts (the moment waypoint k - 1 is done);
- the last leg ends when the last waypoint is reached (the drone then holds there).

Two logs say when: the telemetry log (MISSION_CURRENT changes and MISSION_ITEM_REACHED,
:mod:`missions.flight_report.vehicle_log`), timed by the midpoint of the stream samples around them
(within half a stream period, 10 ms at 50 Hz), and ArduPilot's own DataFlash log, whose MSG
records "Mission: N ..." and "Reached command #N" carry the vehicle's microseconds (within
its 2.5 ms loop). The two differ by a sizeable share of the shortest legs, so the
DataFlash times are the reference the mock is held against (``tests/missions/data/
README.md`` has both); a mock, which writes no DataFlash log, is read from its telemetry
with a stream at every simulation step.

``benchmarks/sitl_leg_times.py`` writes the test data of recorded SITL flights with it.
"""

from __future__ import annotations

import re
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray
from pymavlink import mavutil

from flycrane.errors import FieldProblem, InputError
from missions.export.items import MavCmd, MissionItem
from missions.flight_report.record import FlightRecord
from missions.flight_report.vehicle_log import SeqEvents, read_vehicle_log
from missions.options import GeodeticOrigin
from missions.task.directory import TaskDirectory

#: DataFlash MSG texts of a command's start and of a nav command reached (AP_Mission,
#: ArduCopter 4.5).
_STARTED = re.compile(r"Mission: (\d+) ")
_REACHED = re.compile(r"Reached command #(\d+)")
#: Item fields kept in the test data, in this order (x, y: 1e-7 degree; the rest float32).
MISSION_FIELDS = ("frame", "command", "param1", "param2", "param3", "param4", "x", "y", "z")
#: Parameters the SITL harness sets that are not the plan's (``missions.sitl.harness``).
SITL_ONLY = frozenset({"ARMING_CHECK"})


def spline_waypoints(items: Sequence[MissionItem]) -> tuple[int, ...]:
    """The seqs of the mission's timed waypoints (NAV_SPLINE_WAYPOINT), in order."""
    return tuple(i.seq for i in items if int(i.command) == MavCmd.NAV_SPLINE_WAYPOINT)


def leg_durations(
    started: SeqEvents,
    reached: SeqEvents,
    items: Sequence[MissionItem],
    release_seq: int,
    vehicle: str,
) -> NDArray[np.float64]:
    """Duration of every timed leg [s of the vehicle's clock] (module docstring), from the
    items' starts (MISSION_CURRENT changes, or DataFlash starts) and reached events.

    Raises
    ------
    InputError
        If an event a leg is timed by is missing (the flight did not get that far, or the
        mission is not the one flown).
    """
    waypoints = spline_waypoints(items)
    if not waypoints:
        raise InputError([FieldProblem(vehicle, "the mission has no NAV_SPLINE_WAYPOINT")])
    marks = [(started, seq, "start") for seq in (release_seq, *waypoints[1:])]
    marks.append((reached, waypoints[-1], "reached"))
    times = []
    for events, seq, kind in marks:
        event = events.first(seq)
        if event is None:
            raise InputError([FieldProblem(vehicle, f"no {kind} event for seq {seq}")])
        times.append(event[0])
    return np.diff(np.array(times))


def dataflash_events(path: Path) -> tuple[SeqEvents, SeqEvents]:
    """Item starts and nav items reached, from an ArduPilot DataFlash (``.BIN``) log."""
    log = mavutil.mavlink_connection(str(path))
    rows: dict[str, list[tuple[float, int]]] = {"started": [], "reached": []}
    try:
        while (msg := log.recv_match(type="MSG")) is not None:
            for kind, pattern in (("started", _STARTED), ("reached", _REACHED)):
                if found := pattern.match(msg.Message):
                    rows[kind].append((msg.TimeUS * 1e-6, int(found.group(1))))
    finally:
        log.close()
    events = []
    for kind in ("started", "reached"):
        array = np.array(rows[kind], dtype=float).reshape(-1, 2)
        events.append(SeqEvents(array[:, 0], array[:, 0], array[:, 1].astype(np.int64)))
    return events[0], events[1]


def _dataflash_log(workdir: Path) -> Path:
    """The simulator's last DataFlash log (``logs/LASTLOG.TXT`` names it)."""
    logs = workdir / "logs"
    number = int((logs / "LASTLOG.TXT").read_text(encoding="ascii").split()[0])
    return logs / f"{number:08d}.BIN"


def _float32(value: float) -> float:
    """``value`` as the wire carries it, in its shortest decimal form."""
    return float(str(np.float32(value)))


def mission_rows(items: Sequence[MissionItem]) -> list[list[float]]:
    """The items as compact rows of :data:`MISSION_FIELDS` (seq is the row's index)."""
    return [
        [int(i.frame), int(i.command)]
        + [_float32(getattr(i, f)) for f in ("param1", "param2", "param3", "param4")]
        + [i.x, i.y, _float32(i.z)]
        for i in items
    ]


def flight_record(flight_dir: Path) -> dict[str, Any]:
    """The test data of one recorded SITL flight (module docstring)."""
    flight = FlightRecord.read(flight_dir)
    missions = TaskDirectory(flight.task_dir).missions()
    release = flight.release_seq
    drones = []
    for index, vehicle in enumerate(flight.vehicles):
        name = vehicle.name
        items = missions[index].items
        started, reached = dataflash_events(_dataflash_log(flight_dir / "sitl" / f"sitl{index}"))
        # the origin only places positions; leg times need none
        log = read_vehicle_log(flight_dir / vehicle.tlog, name, GeodeticOrigin())
        drones.append(
            {
                "name": name,
                "parameters": {
                    k: v for k, v in flight.parameters[name].items() if k not in SITL_ONLY
                },
                "legs_s": [round(float(t), 4) for t in leg_durations(
                    started, reached, items, release, name)],
                "legs_tlog_s": [round(float(t), 3) for t in leg_durations(
                    log.current, log.reached, items, release, name)],
                "mission": mission_rows(items),
            }
        )  # fmt: skip
    return {"flight": flight_dir.name, "task": Path(flight.task_dir).name, "release_seq": release,
            "drones": drones}  # fmt: skip
