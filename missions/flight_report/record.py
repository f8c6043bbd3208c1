"""A recorded flight's own facts (``flight.json``): what the ground station did and when,
beside the vehicles' tlogs, and the names of every file of a flight's directory. The SITL
harness writes it (:mod:`missions.sitl.flight`); the flight report reads it."""

from __future__ import annotations

import json
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

from flycrane.errors import FieldProblem, InputError
from missions.task.documents import DRONES
from missions.viewer.flown import FLOWN_FILE

FLIGHT_FILE = "flight.json"
#: An executor's record beside it (:class:`missions.execution.record.ExecutionRecord`).
EXECUTION_FILE = "execution.json"
#: What the flight report writes (and the viewer's :data:`FLOWN_FILE`).
REPORT_FILE, PLOT_FILE = "report.json", "report.png"
MCAP_FILE = "flight.mcap"
#: Every file of a flight's directory: its record, the vehicles' logs, its report.
FLIGHT_FILES = (
    FLIGHT_FILE, EXECUTION_FILE, *(f"drone{k}.tlog" for k in (1, 2, 3)),
    REPORT_FILE, PLOT_FILE, FLOWN_FILE, MCAP_FILE,
)  # fmt: skip


def fresh_flight_directory(out_dir: Path) -> None:
    """Make ``out_dir`` for a flight and remove an earlier flight's files from it: beside
    the new flight's logs, the old report would read as the new flight's."""
    out_dir.mkdir(parents=True, exist_ok=True)
    for name in FLIGHT_FILES:
        (out_dir / name).unlink(missing_ok=True)


@dataclass(frozen=True)
class VehicleRecord:
    """One vehicle's part of a recorded flight."""

    name: str
    system_id: int
    tlog: str  #: file name in the flight directory
    rate: float  #: achieved simulated seconds per wall second
    release_sent_s: float  #: when its release was sent [s on the logs' time base]
    release_confirmed_s: float  #: when MISSION_CURRENT confirmed it [s, same base]
    #: how far its clock led the latest vehicle's before the release [s of simulated
    #: time], as measured before and after the harness brought them together
    #: (:mod:`missions.sitl.clocks`); empty where the release was refused
    clock_lead_s: tuple[float, ...] = ()


@dataclass(frozen=True)
class FlightRecord:
    """What ``flight.json`` holds: the facts of the flight that the logs do not."""

    task_dir: str
    speedup: float
    hold_seq: int
    release_seq: int
    end_seq: tuple[int, ...]
    planned_duration_s: float
    vehicles: tuple[VehicleRecord, ...]
    parameters: dict[str, dict[str, float]]  #: what was set, per vehicle
    release_delays: tuple[float, ...]
    parameter_differences: tuple[str, ...]  #: read back unlike the plan's .parm
    mode: str = "missions"  #: who flew the plan (:mod:`missions.execution`)
    refused: tuple[str, ...] = ()  #: why the release was refused (none: released)
    faults: tuple[dict[str, Any], ...] = ()  #: injected: kind, drone, plan time, common time

    def as_dict(self) -> dict[str, Any]:
        return asdict(self)

    def write(self, flight_dir: Path) -> Path:
        path = flight_dir / FLIGHT_FILE
        path.write_text(json.dumps(self.as_dict(), indent=2) + "\n", encoding="utf-8")
        return path

    @classmethod
    def read(cls, flight_dir: Path) -> FlightRecord:
        """From ``flight_dir/flight.json``.

        Raises
        ------
        InputError
            No such file, or not a flight record of this version (field ``flight``).
        """
        path = flight_dir / FLIGHT_FILE
        try:
            data = json.loads(path.read_text(encoding="utf-8"))
            record = cls(
                task_dir=str(data["task_dir"]),
                speedup=float(data["speedup"]),
                hold_seq=int(data["hold_seq"]),
                release_seq=int(data["release_seq"]),
                end_seq=tuple(int(s) for s in data["end_seq"]),
                planned_duration_s=float(data["planned_duration_s"]),
                vehicles=tuple(VehicleRecord(**v) for v in data["vehicles"]),
                parameters=dict(data["parameters"]),
                release_delays=tuple(float(d) for d in data["release_delays"]),
                parameter_differences=tuple(data["parameter_differences"]),
                mode=str(data.get("mode", "missions")),
                refused=tuple(data.get("refused", ())),
                faults=tuple(data.get("faults", ())),
            )
            for name, listed in (("vehicles", record.vehicles), ("end_seq", record.end_seq)):
                if len(listed) != len(DRONES):
                    raise ValueError(f"{name}: {len(listed)} listed, a flight has {len(DRONES)}")
            return record
        except KeyError as error:
            reason = f"{path}: no field {error} (not a flight record of this version)"
            raise InputError([FieldProblem("flight", reason)]) from None
        except (OSError, ValueError, TypeError) as error:
            raise InputError([FieldProblem("flight", f"{path}: {error}")]) from None
