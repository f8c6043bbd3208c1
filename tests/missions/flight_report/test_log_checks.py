"""The flight report refuses logs that cannot be the flight, and judges no more than the
logs show: three mock ArduCopters fly the Rescue (``test_replay.py``'s harness) and record a
tlog each; the tests cut, corrupt, repeat and swap those tlogs as a user's could be."""

from __future__ import annotations

import json
import math
import shutil
from dataclasses import replace
from pathlib import Path

import pytest

from flycrane.cli import main
from missions.flight_report import report_tlogs
from missions.mock.config import Imperfections
from tests.missions.mock.test_replay import Exported, fly
from tests.missions.mock.test_replay import rescue as rescue

from ..mavlink.conftest import no_leaked_threads  # noqa: F401 (autouse fixture)


@pytest.fixture(scope="module")
def tlogs(rescue: Exported, tmp_path_factory: pytest.TempPathFactory) -> list[Path]:
    directory = tmp_path_factory.mktemp("tlogs")
    fly(rescue, [Imperfections()] * 3, tlog_dir=directory)
    return [directory / f"drone{k}.tlog" for k in (1, 2, 3)]


def _cut(tlog: Path, out: Path, fraction: float) -> Path:
    out.write_bytes(tlog.read_bytes()[: int(tlog.stat().st_size * fraction)])
    return out


def _report(rescue: Exported, tlogs: list[Path], out: Path, capsys) -> tuple[int, dict, str]:
    args = ["flight-report", str(rescue.directory), "--tlogs", *map(str, tlogs)]
    status = main([*args, "--out", str(out)])
    error = capsys.readouterr().err
    report = json.loads((out / "report.json").read_text()) if status in (0, 1) else {}
    return status, report, error


def test_logs_that_end_early_judge_what_they_show_and_say_so(rescue, tlogs, tmp_path, capsys):
    """Cut at 60 % of their bytes the three logs end mid-flight: not safe, each drone named
    with where its log ends, and no sample judged after the first of those ends."""
    cut = [_cut(t, tmp_path / t.name, 0.6) for t in tlogs]
    status, report, _ = _report(rescue, cut, tmp_path / "report", capsys)
    assert status == 1 and not report["verdict"]["safe"]
    reasons = report["verdict"]["reasons"]
    assert [r.split("'")[0] for r in reasons] == ["drone1", "drone2", "drone3"]
    ends = [float(r.split("ends at ")[1].split(" s")[0]) for r in reasons]
    assert max(ends) < report["planned_duration"] - 1.0
    assert max(report["series"]["time"]["mission"]) <= min(ends) + 1e-9
    estimated = report["estimated"]
    assert estimated["feasible"] and estimated["collision_free"]  # the load is not blamed


def test_one_log_that_ends_early_is_named_not_the_load(rescue, tlogs, tmp_path, capsys):
    """drone1's log held at its last fix for the rest of the flight made the load read
    unsafe; the report now names the log and judges the flight while all three show it."""
    given = [_cut(tlogs[0], tmp_path / "d1.tlog", 0.3), *tlogs[1:]]
    status, report, _ = _report(rescue, given, tmp_path / "report", capsys)
    assert status == 1
    (reason,) = report["verdict"]["reasons"]
    assert reason.startswith("drone1's log ends at") and "not judged" in reason
    assert report["estimated"]["feasible"] and report["estimated"]["collision_free"]


def test_a_whole_flight_is_safe_and_its_report_is_strict_json(rescue, tlogs, tmp_path, capsys):
    status, report, _ = _report(rescue, tlogs, tmp_path / "report", capsys)
    assert status == 0 and report["verdict"]["safe"]

    def refuse(constant: str) -> None:
        raise ValueError(f"not JSON: {constant}")

    for name in ("report.json", "flown.json"):
        json.loads((tmp_path / "report" / name).read_text(), parse_constant=refuse)


def test_a_figure_without_a_finite_value_is_null_in_the_json(rescue, tlogs):
    """An unsafe flight's highest cost is infinite (no cable can hold the load): JSON has no
    infinity, and JavaScript's JSON.parse refuses the file that writes one."""
    report, _ = report_tlogs(rescue.directory, tlogs)
    estimated = replace(report.estimated, highest_cost=math.inf, least_clearance=math.nan)
    document = replace(report, estimated=estimated).as_dict()
    text = json.dumps(document, allow_nan=False)  # raises on a float that is not finite
    assert json.loads(text)["estimated"]["highest_cost"] is None
    assert json.loads(text)["estimated"]["least_clearance"] is None


@pytest.mark.parametrize(
    ("order", "reason"),
    [((0, 0, 0), "are one log"), ((1, 0, 2), "the 2nd, 1st, 3rd given 0.0")],
)
def test_logs_of_other_drones_are_refused_by_name(rescue, tlogs, tmp_path, capsys, order, reason):
    """One drone's log given for all three, or drone 1's and 2's swapped, was judged as a
    flight whose load was lost."""
    given = [tlogs[k] for k in order]
    status, _, error = _report(rescue, given, tmp_path / "report", capsys)
    assert status == 2, error
    assert error.startswith("flycrane flight-report: error: tlogs:") and reason in error


def test_a_task_whose_mission_file_was_emptied_is_named(rescue, tlogs, tmp_path, capsys):
    task = shutil.copytree(rescue.directory, tmp_path / "task")
    mission = json.loads((task / "drone2.mission.json").read_text())
    (task / "drone2.mission.json").write_text(json.dumps({**mission, "items": []}))
    assert main(["flight-report", str(task), "--tlogs", *map(str, tlogs)]) == 2
    error = capsys.readouterr().err
    assert "drone2.mission.json does not hold what this version writes" in error
