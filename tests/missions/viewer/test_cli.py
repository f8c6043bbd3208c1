"""``flycrane view``: the page of a planned task, with a flight's flown tracks, written to
disk; a flight of another task, or a directory without a flight report, is refused by name."""

from __future__ import annotations

import json
import shutil

import numpy as np
import pytest

from flycrane.cli import main
from missions.flight_report.record import FlightRecord, VehicleRecord
from missions.task.pipeline import run_task
from missions.viewer import FLOWN_FILE, PAGE_FILE
from tests.missions.viewer.test_document import TASK
from tests.missions.viewer.test_page import by_type, parse


@pytest.fixture(scope="module")
def planned(tmp_path_factory):
    out = tmp_path_factory.mktemp("shapes")
    assert run_task(TASK, out).status == "done"
    return out, json.loads((out / "tracks.json").read_text(encoding="utf-8"))


def _flight(directory, task_dir, tracks, shift):
    """A flight's directory as a SITL flight's report leaves it: its record names the task;
    its drones flew the plan moved by ``shift``."""
    directory.mkdir()
    vehicles = tuple(
        VehicleRecord(f"drone{k}", k, f"drone{k}.tlog", 10.0, 0.0, 0.0, ()) for k in (1, 2, 3)
    )
    FlightRecord(
        task_dir=str(task_dir), speedup=2.0, hold_seq=2, release_seq=3, end_seq=(9, 9, 9),
        planned_duration_s=tracks["time"][-1], vehicles=vehicles, parameters={},
        release_delays=(), parameter_differences=(),
    ).write(directory)  # fmt: skip
    flown = {
        "source": "flight-true",
        "time": tracks["time"],
        "drones_enu": (np.array(tracks["drones_enu"]) + shift).tolist(),
    }
    (directory / FLOWN_FILE).write_text(json.dumps(flown), encoding="utf-8")
    return directory


def _document(page_path):
    (data,) = by_type(parse(page_path.read_text(encoding="utf-8")), "application/json")
    return json.loads(data["text"])


def test_page_of_a_task_with_its_flight(planned, tmp_path, capsys):
    """The flown drones, shifted by d, carry the platform shifted by d (the hanging load
    moves with its drones): the page holds the flight's data, not the plan's again."""
    task_dir, tracks = planned
    shift = np.array([0.2, 0.0, -0.1])
    flight = _flight(tmp_path / "flight", task_dir, tracks, shift)
    out = tmp_path / "page.html"
    assert main(["view", str(task_dir), "--flight", str(flight), "--out", str(out)]) == 0
    assert capsys.readouterr().out.strip().endswith(str(out))
    document = _document(out)
    assert document["flown"]["source"] == "flight-true"
    q = np.array(tracks["configurations"])
    np.testing.assert_allclose(document["flown"]["platform_position"], q[:, :3] + shift, atol=1e-5)
    assert document["planned"]["time"][0] == pytest.approx(tracks["time"][0])


def test_page_without_a_flight_goes_beside_the_task(planned, tmp_path):
    task_dir, _ = planned
    copy = shutil.copytree(task_dir, tmp_path / "task")
    assert main(["view", str(copy)]) == 0
    assert _document(copy / PAGE_FILE)["flown"] is None


def test_a_flight_of_a_copy_of_the_task_is_its_flight(planned, tmp_path):
    task_dir, tracks = planned
    copy = shutil.copytree(task_dir, tmp_path / "task")
    flight = _flight(tmp_path / "flight", task_dir, tracks, np.zeros(3))
    assert main(["view", str(copy), "--flight", str(flight)]) == 0


def test_a_flight_of_another_task_is_refused(planned, tmp_path, capsys):
    task_dir, tracks = planned
    other = shutil.copytree(task_dir, tmp_path / "other")
    (other / "tracks.json").write_text(json.dumps({**tracks, "time": tracks["time"][::-1]}))
    flight = _flight(tmp_path / "flight", other, tracks, np.zeros(3))
    out = tmp_path / "x.html"
    assert main(["view", str(task_dir), "--flight", str(flight), "--out", str(out)]) == 2
    error = capsys.readouterr().err
    assert "--flight" in error and str(other) in error
    assert not out.exists()


@pytest.mark.parametrize(
    ("args", "field"),
    [(["--flight", "{tmp}"], "--flight"), (["--out", ""], "--out"), ([], "task.json")],
)
def test_bad_arguments_are_named(planned, tmp_path, capsys, args, field):
    task_dir, _ = planned
    given = str(tmp_path) if field == "task.json" else str(task_dir)
    args = [a.replace("{tmp}", str(tmp_path)) for a in args]
    assert main(["view", given, *args]) == 2
    error = capsys.readouterr().err
    assert error.startswith("flycrane view: error:") and field in error
