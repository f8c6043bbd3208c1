"""The ``flycrane`` command line: tables, JSON, and clean errors with a non-zero exit."""

from __future__ import annotations

import json
import subprocess
import sys

import pytest

from flycrane.cli import main


def test_statics_json_on_defaults(capsys):
    assert main(["statics", "--json"]) == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["feasible"] is True
    assert summary["cables"][0]["nominal_tension"] == pytest.approx(3.11, abs=0.01)
    assert summary["drones"][2]["thrust_bound"] == pytest.approx(17.14, abs=0.01)
    assert summary["violations"] == []


def test_statics_table_names_violations(capsys):
    assert main(["statics", "--q", "0", "0", "5", "0", "0", "0", "1.4", "1.4", "1.4"]) == 0
    out = capsys.readouterr().out
    assert "feasible: no" in out
    assert "cable 1: lowest tension" in out
    assert "cost (normalized): inf" in out


def test_singular_configuration_prints_without_nan(capsys):
    assert main(["statics", "--json", "--q", "0", "0", "5", "0", "0", "0", "0", "0", "0"]) == 0
    out = capsys.readouterr().out
    assert "NaN" not in out and "Infinity" not in out
    assert json.loads(out)["singular"] is True


def test_a_singular_configuration_s_table_says_its_margins_are_undefined(capsys):
    """No tensions, so no margins: "inf" would read as infinitely safe."""
    assert main(["statics", "--q", "0", "0", "5", "0", "0.2", "0", "0", "0", "0"]) == 0
    table = capsys.readouterr().out
    cables = [line for line in table.splitlines() if line.lstrip().startswith("1  ")]
    assert cables and all("inf" not in line and "n/a" in line for line in cables)
    assert "screw Jacobian is singular" in table


def test_an_interrupted_command_says_so_without_a_traceback(monkeypatch, capsys):
    def interrupted(*_: object) -> None:
        raise KeyboardInterrupt

    monkeypatch.setattr("flycrane.cli.evaluate_statics", interrupted)
    assert main(["statics"]) == 130
    assert capsys.readouterr().err == "flycrane statics: interrupted\n"


@pytest.mark.parametrize(
    ("args", "message"),
    [(["--write", ""], "--write: an empty file name"),
     (["--write", "{missing}/x.toml"], "--write: {missing}/x.toml: No such file or directory"),
     (["--write", "{folder}"], "--write: {folder}: Is a directory")],
)  # fmt: skip
def test_a_system_file_that_cannot_be_written_names_the_option(args, message, tmp_path, capsys):
    where = {"missing": tmp_path / "missing", "folder": tmp_path / "d.toml"}
    where["folder"].mkdir()
    assert main(["system", *(a.format(**where) for a in args)]) == 2
    captured = capsys.readouterr()
    assert message.format(**where) in captured.err and not captured.out


def test_an_empty_out_is_refused_not_taken_for_the_current_directory(tmp_path, capsys):
    assert main(["bench", "--scenes", "rescue", "--runs", "1", "--out", ""]) == 2
    assert "--out: an empty directory name" in capsys.readouterr().err


def test_bad_input_is_a_message_and_exit_status_2(tmp_path, capsys):
    assert main(["statics", "--q", "0", "0", "5", "0", "-1", "0", "1", "1", "1"]) == 2
    assert "q.theta" in capsys.readouterr().err
    bad = tmp_path / "bad.toml"
    bad.write_text("platform_mass = -1\n", encoding="utf-8")
    assert main(["statics", "--system", str(bad)]) == 2
    err = capsys.readouterr().err
    assert "platform_mass" in err and "Traceback" not in err


def test_a_configuration_beyond_the_schemas_bounds_is_refused(capsys):
    """1e300 m would read as a singular Jacobian, not as an input out of range."""
    assert main(["statics", "--q", "1e300", "0", "5", "0", "0.2", "0", "1", "1", "nan"]) == 2
    err = capsys.readouterr().err
    assert "q.x: Input should be less than or equal to 10000" in err
    assert "q.alpha3: Input should be a finite number" in err


@pytest.mark.parametrize(
    ("option", "value"),
    [("--runs", "0"), ("--runs", "100000000"), ("--budget", "-1"), ("--budget", "inf"),
     ("--budget", "nan"), ("--step", "-0.1"), ("--step", "0"), ("--workers", "0"),
     ("--step", "20000"), ("--step", "1e300"),
     ("--workers", "two"), ("--workers", "1000"), ("--cluster", "garbage"),
     ("--cluster", "tcp://host"), ("--cluster", "dask://host:0"),
     ("--cluster", "tls://host:8786")],
)  # fmt: skip
def test_a_bad_bench_setting_is_refused_before_any_run(option, value, tmp_path, capsys):
    """argparse exits 2 naming the option; nothing is planned or written."""
    out = tmp_path / "bench"
    with pytest.raises(SystemExit) as stopped:
        main(["bench", "--scenes", "rescue", "--planners", "rrt", "--out", str(out),
              option, value])  # fmt: skip
    assert stopped.value.code == 2
    err = capsys.readouterr().err
    assert f"argument {option}:" in err and "Traceback" not in err
    assert not out.exists()


def test_system_file_written_by_the_cli_loads_back(tmp_path, capsys):
    path = tmp_path / "system.toml"
    assert main(["system", "--write", str(path)]) == 0
    assert main(["statics", "--system", str(path), "--json"]) == 0
    assert "wrote" in capsys.readouterr().out


def test_a_command_loads_only_its_own_plug_in():
    """Each plug-in command imports its own stack; running one must not pay for the others,
    and a command line naming none (help, a typo) must still list them all."""
    probe = (
        "import sys; from flycrane.cli import build_parser; "
        "build_parser(['plan', '--out', 'x']); "
        "print(sorted(m for m in ('missions.sitl.cli', 'missions.flight_report', "
        "'missions.mock.autopilot', 'service.cli') if m in sys.modules)); "
        "names = build_parser(['--help'])._subparsers._group_actions[0].choices; "
        "print(sorted(names))"
    )
    run = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, check=True)
    loaded, names = run.stdout.splitlines()
    assert loaded == "[]"
    for command in ("plan", "fly-sitl", "flight-report", "mock-autopilot", "serve", "statics"):
        assert repr(command) in names


def test_the_command_exits_with_the_status_and_output_of_main():
    """``python -m flycrane.cli`` (and the console script) run :func:`flycrane.cli.run`,
    which skips the interpreter's final garbage collection: output and status survive it."""
    ok = subprocess.run(
        [sys.executable, "-m", "flycrane.cli", "statics", "--json"],
        capture_output=True,
        text=True,
    )
    assert ok.returncode == 0 and json.loads(ok.stdout)["feasible"] is True
    bad = subprocess.run(
        [sys.executable, "-m", "flycrane.cli", "statics", "--q", *"0 0 5 0 -1 0 1 1 1".split()],
        capture_output=True,
        text=True,
    )
    assert bad.returncode == 2 and "q.theta" in bad.stderr


def test_bench_runs_a_scene_file_given_by_a_relative_path_end_to_end(tmp_path):
    """``flycrane bench --scenes sites/my_scene.toml`` (issue 22): the table, the margins and
    a figure named after the file, not a crash after every seed was computed."""
    from flycrane.world.scene import scene_path

    (tmp_path / "sites").mkdir()
    (tmp_path / "sites" / "my_scene.toml").write_text(scene_path("rescue").read_text())
    command = [sys.executable, "-m", "flycrane.cli", "bench", "--scenes", "sites/my_scene.toml",
               "--planners", "trrt", "--runs", "1", "--budget", "30", "--workers", "1",
               "--out", "results"]  # fmt: skip
    done = subprocess.run(command, cwd=tmp_path, capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr[-2000:]
    assert "sites/my_scene.toml" in done.stdout and "least" in done.stdout.lower()
    assert (tmp_path / "results" / "fig6_my_scene.png").stat().st_size > 0
    assert (tmp_path / "results" / "runs.csv").read_text().count("\n") == 2


def test_bench_help_names_the_scenes_and_the_planners(capsys):
    with pytest.raises(SystemExit):
        main(["bench", "--help"])
    text = " ".join(capsys.readouterr().out.split())
    assert "rescue" in text and "puzzle_first" in text and "scene files" in text
    assert "bitrrt" in text and "ompl-rrtconnect" in text
