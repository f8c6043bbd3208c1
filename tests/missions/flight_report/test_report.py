"""The flight report on flights whose truth we impose: three mock ArduCopters fly the Rescue
missions (``tests/missions/test_replay.py``'s harness, lock-step simulated clock) and
record a tlog each, as a ground station would; ``flycrane flight-report`` reads the three
tlogs back with nothing else.

What is imposed and must come back: the release offsets (exact simulated times,
``SimClock.held(at=...)``), and that the mocks fly the plan's model (so the load stays
within the plan's margins and the drones in step). The MCAP log is read back with the
``mcap`` library.
"""

from __future__ import annotations

import json
import struct
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from mcap.reader import make_reader
from pymavlink.dialects.v20 import ardupilotmega

from flycrane.cli import main
from flycrane.errors import InputError
from flycrane.planning.planners import PlannerOptions
from missions.execution.record import ExecutionRecord
from missions.flight_report.record import EXECUTION_FILE, FlightRecord, VehicleRecord
from missions.mock.config import Imperfections
from missions.task.spec import TaskSpec
from tests.missions.mock.test_replay import Exported, export, fly, late_drones
from tests.missions.mock.test_replay import rescue as rescue

from ..mavlink.conftest import no_leaked_threads  # noqa: F401 (autouse fixture)


def report_of(exported: Exported, tmp_path: Path, delays: list[float]) -> dict:
    """Fly with ``delays``, run ``flycrane flight-report`` on the tlogs, return report.json."""
    fly(exported, [Imperfections()] * 3, release_delays=delays, tlog_dir=tmp_path)
    tlogs = [str(tmp_path / f"drone{k}.tlog") for k in (1, 2, 3)]
    command = [sys.executable, "-m", "flycrane.cli", "flight-report", str(exported.directory),
               "--tlogs", *tlogs, "--out", str(tmp_path / "report")]  # fmt: skip
    done = subprocess.run(command, capture_output=True, text=True, timeout=600)
    assert done.returncode in (0, 1), done.stderr[-3000:]  # 0 safe, 1 unsafe
    report = json.loads((tmp_path / "report" / "report.json").read_text())
    assert (done.returncode == 0) == report["verdict"]["safe"]
    return report


def test_a_flight_in_step_is_reported_safe_with_its_figures_in_the_log(rescue, tmp_path):
    report = report_of(rescue, tmp_path, [0.0, 0.0, 0.0])
    assert report["true"] is None  # the mock sends no SIM_STATE: estimates only
    estimated = report["estimated"]
    assert report["verdict"]["safe"], report["verdict"]["reasons"]
    assert report["release_spread"] <= 0.04  # two steps of the 20 ms simulation
    flown, planned = report["timing"]["flown_duration"], report["planned_duration"]
    assert flown == pytest.approx(planned, abs=0.1)  # the mocks fly the plan's model
    assert estimated["converged"] and estimated["feasible"] and estimated["collision_free"]
    assert estimated["inter_drone_error_p95"] <= 0.05

    log = tmp_path / "report" / "flight.mcap"
    with log.open("rb") as stream:
        messages = make_reader(stream).iter_messages(["/flight/estimated"])
        figures = [json.loads(message.data) for _, _, message in messages]
    with log.open("rb") as stream:
        metadata = {m.name: json.loads(m.metadata["json"])
                    for m in make_reader(stream).iter_metadata()}  # fmt: skip
    assert len(figures) == estimated["samples"]
    clearance = min(f["clearance"] for f in figures)
    assert clearance == pytest.approx(estimated["least_clearance"])
    assert max(max(f["error_in_time"]) for f in figures) == pytest.approx(
        max(estimated["error_in_time_max"])
    )
    assert metadata["report"]["verdict"] == report["verdict"]


def test_a_release_beyond_the_tolerance_is_reported_unsafe_and_its_spread_measured(
    rescue, tmp_path
):
    late = 2.5 * rescue.tolerance["start_offset"]
    delays = [late if k in late_drones(rescue.tolerance["start_offset_case"]) else 0.0
              for k in range(3)]  # fmt: skip
    report = report_of(rescue, tmp_path, delays)
    assert report["release_spread"] == pytest.approx(late, abs=0.04)
    assert not report["verdict"]["safe"]
    assert any("release spread" in r for r in report["verdict"]["reasons"])
    progress = np.array(report["series"]["progress"]["plan_time"], dtype=float)
    assert np.nanmax(np.nanmax(progress, axis=1) - np.nanmin(progress, axis=1)) >= 0.5 * late


def test_a_set_down_load_may_rest_on_its_surfaces_through_the_final_hold(
    tmp_path_factory, tmp_path
):
    """bitrrt's Rescue path with its formation polished (seed 0): in the hold after the
    set-down leg, the mocks' positions put the footbridge 0.054 m into the west roof, and
    a report whose contact window closed with the leg called the flight unsafe. The
    load is meant to stay down: contact with the set-down's surfaces is allowed to the end,
    and nothing else is."""
    task = TaskSpec(planner=PlannerOptions(algorithm="bitrrt", seed=0, time_budget=60, polish=True))
    exported = export(task, tmp_path_factory)
    report = report_of(exported, tmp_path, [0.0, 0.0, 0.0])
    assert report["verdict"]["safe"], report["verdict"]["reasons"]
    assert exported.set_down is not None
    estimated = report["estimated"]
    # The least clearance is to a set-down surface after the leg began, or positive.
    assert estimated["least_clearance"] > 0 or (
        estimated["least_clearance_at"] >= exported.set_down["start_time"]
        and any(s in estimated["least_clearance_bodies"] for s in exported.set_down["surfaces"])
    )


def test_a_clocked_flight_whose_logs_end_before_its_start_is_named_not_a_traceback(
    rescue, tmp_path, capsys
):
    """A stream flight whose team stopped before the plan's clock ran and whose logs end
    there (a ground that fell behind its vehicles' messages): ``flycrane flight-report``
    names the drone and by how much, and exits 2."""
    unix0, start = 1.8e9, 1.8e9 + 10.0
    for k, mission in enumerate(rescue.missions, start=1):
        mav = ardupilotmega.MAVLink(None, srcSystem=k)
        with (tmp_path / f"drone{k}.tlog").open("wb") as log:
            for i in range(50):  # 5 s at 10 Hz, drone k's log ending k / 10 s earlier
                boot_ms = 100 * (i + 10 - k)
                messages = [
                    mav.system_time_encode(int((unix0 + boot_ms / 1000) * 1e6), boot_ms),
                    mav.global_position_int_encode(
                        boot_ms, mission.items[0].x, mission.items[0].y, 0, 0, 0, 0, 0, 0
                    ),
                ]
                for message in messages:
                    log.write(struct.pack(">Q", int((unix0 + boot_ms / 1000) * 1e6)))
                    log.write(message.pack(mav))
    vehicles = tuple(VehicleRecord(f"drone{k}", k, f"drone{k}.tlog", 1.0, 0.0, 0.0)
                     for k in (1, 2, 3))  # fmt: skip
    FlightRecord(
        task_dir=str(rescue.directory), speedup=1.0, hold_seq=rescue.hold_seq,
        release_seq=rescue.release_seq, end_seq=(0, 0, 0), planned_duration_s=10.0,
        vehicles=vehicles, parameters={}, release_delays=(0.0, 0.0, 0.0),
        parameter_differences=(), mode="stream",
    ).write(tmp_path)  # fmt: skip
    record = ExecutionRecord(mode="stream", start=start, duration=10.0)
    (tmp_path / EXECUTION_FILE).write_text(json.dumps(record.as_dict()))
    assert main(["flight-report", str(tmp_path)]) == 2
    # drone 3's log ends first, at 5.6 s of its boot and of the UNIX time from unix0
    assert "drone3: its log ends 4.40 s before the plan's start" in capsys.readouterr().err


def test_a_flight_record_missing_a_field_says_which(tmp_path):
    """The reason was a KeyError's bare text, 'task_dir'."""
    (tmp_path / "flight.json").write_text("{}", encoding="utf-8")
    with pytest.raises(InputError, match="no field 'task_dir'"):
        FlightRecord.read(tmp_path)


@pytest.mark.parametrize("count", [2, 4])
def test_a_flight_record_of_other_than_three_vehicles_is_refused(tmp_path, count):
    """Two or four vehicles listed went on to a broadcasting error or an IndexError."""
    vehicles = [VehicleRecord(f"drone{k}", k, f"drone{k}.tlog", 1.0, 0.0, 0.0) for k in (1, 2, 3)]
    record = FlightRecord(
        task_dir="task", speedup=1.0, hold_seq=2, release_seq=3, end_seq=(9, 9, 9),
        planned_duration_s=10.0, vehicles=tuple(vehicles), parameters={}, release_delays=(),
        parameter_differences=(),
    )  # fmt: skip
    document = record.as_dict()
    document["vehicles"] = (document["vehicles"] * 2)[:count]
    (tmp_path / "flight.json").write_text(json.dumps(document), encoding="utf-8")
    with pytest.raises(InputError, match=f"vehicles: {count} listed, a flight has 3"):
        FlightRecord.read(tmp_path)
