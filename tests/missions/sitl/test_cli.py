"""``flycrane fly-sitl``'s bad arguments: a message naming the setting and a non-zero exit
before any simulator starts (no simulator needed)."""

from __future__ import annotations

import subprocess
import sys

import pytest

from missions.flight_report.record import FLIGHT_FILES, fresh_flight_directory
from missions.sitl.faults import FaultPlan


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--speedup", "0"], "fly-sitl: speedup: Input should be greater than 0"),
        (["--speedup", "-3"], "fly-sitl: speedup: Input should be greater than 0"),
        (["--boot-speedup", "60"], "fly-sitl: boot_speedup: Input should be less than or equal"),
        (["--fault", "motor:1:5:0.8:5"], "argument --fault: fault motor 5: 1-4"),
        (["--fault", "gps:1:5:0:2"], "'gps:1:5:0:2': only a motor fault names a motor"),
        (["--fault", "gps:2:-3"], "fault time -3.0: seconds of plan time, at least 0"),
        (["--fault", "gps:2:nan"], "fault time nan: seconds of plan time, at least 0"),
        (["--fault", "gps:2:8:0.5"], "'gps:2:8:0.5': a gps fault takes no VALUE"),
        (["--fault", "gpss:2:8"], "fault kind 'gpss': one of gps, link, mode, motor, late"),
        (["--fault", "link:one:8"], "DRONE and MOTOR are whole numbers, AT and VALUE numbers"),
        (["--fault", "motor:1:5"], "'motor:1:5': a motor fault needs VALUE"),
        (["--fault", "motor:1:5:1.5:2"], "motor thrust fraction 1.5: at least 0 and below 1"),
        (["--fault", "late:2:0:-1"], "late start -1.0: seconds, more than 0"),
        (["--fault", "late:2:4:1"], "fault time 4.0: a late start strikes at the start, 0"),
        (["--parameter", "SIM_WIND_SPD=inf"], "expected NAME=VALUE, a finite number"),
        (["--parameter", "=3"], "expected NAME=VALUE, a finite number, got '=3'"),
        # each used to boot three simulators first, then fail, hang or fly
        (["--rate-hz", "0"], "argument --rate-hz: 0 is outside 10-50 Hz"),
        (["--rate-hz", "nan"], "argument --rate-hz: nan is outside 10-50 Hz"),
        (["--release-delays", "nan", "0", "0"], "argument --release-delays: nan is outside"),
        (["--release-delays", "1e9", "0", "0"], "argument --release-delays: 1e9 is outside"),
        (["--release-delays", "-1", "0", "0"], "argument --release-delays: -1 is outside 0-60 s"),
        (["--lead", "0.5", "0"], "argument --lead: 0.5 is outside 0-0.3 s"),
    ],
)
def test_a_bad_argument_is_refused_with_its_name(args, message, tmp_path):
    done = subprocess.run(
        [sys.executable, "-m", "flycrane.cli", "fly-sitl", str(tmp_path), "--out",
         str(tmp_path / "out"), "--shared-network", *args],
        capture_output=True, text=True, timeout=60,
    )  # fmt: skip
    assert done.returncode == 2
    assert message in done.stderr
    assert "Traceback" not in done.stderr
    assert not (tmp_path / "out").exists()


def test_a_motor_fault_names_its_motor_or_weakens_motor_1():
    assert FaultPlan.parse("motor:2:7.5:0.8:3") == FaultPlan("motor", 2, 7.5, 0.8, motor=3)
    assert FaultPlan.parse("motor:2:7.5:0.8").motor == 1


def test_the_process_that_only_starts_the_flight_does_not_load_its_stack():
    """``fly-sitl`` runs itself again in a private network namespace; the first process
    parses the command line and starts the second, so it must not load the flight's stack
    (MAVLink, the autopilot model's kernels, the report), which took it 2-4 s."""
    probe = (
        "import sys; from flycrane.cli import build_parser; "
        "build_parser(['fly-sitl', 'task', '--fault', 'motor:1:5:0.8']).parse_args("
        "['fly-sitl', 'task', '--fault', 'motor:1:5:0.8']); "
        "print(sorted(m for m in ('missions.sitl.harness', 'missions.flight_report', "
        "'missions.execution.executor', 'pymavlink.mavutil', 'numba') if m in sys.modules))"
    )
    run = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, check=True)
    assert run.stdout.strip() == "[]"


@pytest.mark.parametrize("mode", ["missions", "stream"])
def test_a_fault_after_the_plans_end_is_refused_before_any_simulator_starts(mode, rescue, tmp_path):
    """A fault that would never strike is refused, not flown as a healthy flight."""
    done = subprocess.run(
        [sys.executable, "-m", "flycrane.cli", "fly-sitl", str(rescue), "--out",
         str(tmp_path / "out"), "--shared-network", "--mode", mode, "--fault", "gps:2:1000"],
        capture_output=True, text=True, timeout=120,
    )  # fmt: skip
    assert done.returncode == 2
    assert "fly-sitl: fault: gps:2:1000 strikes at or after the plan's end at" in done.stderr
    assert "Traceback" not in done.stderr
    assert not (tmp_path / "out").exists()


def test_an_out_that_is_a_file_is_refused_naming_it(tmp_path):
    (tmp_path / "drone1.parm").write_text("mine", encoding="utf-8")
    done = subprocess.run(
        [sys.executable, "-m", "flycrane.cli", "fly-sitl", str(tmp_path), "--out",
         str(tmp_path / "drone1.parm"), "--shared-network"],
        capture_output=True, text=True, timeout=60,
    )  # fmt: skip
    assert done.returncode == 2
    assert f"--out: {tmp_path / 'drone1.parm'}: exists and is not a directory" in done.stderr
    assert (tmp_path / "drone1.parm").read_text(encoding="utf-8") == "mine"


def test_a_new_flight_clears_the_last_flight_s_files_and_no_others(tmp_path):
    """Beside a new flight's logs, the last flight's report would read as the new one's."""
    for name in (*FLIGHT_FILES, "notes.txt"):
        (tmp_path / name).write_text("old", encoding="utf-8")
    fresh_flight_directory(tmp_path)
    assert [p.name for p in tmp_path.iterdir()] == ["notes.txt"]
    assert {"flight.json", "report.json", "drone2.tlog"} <= set(FLIGHT_FILES)
