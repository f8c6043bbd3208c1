"""The whole job on the default Rescue task, task resolution errors, and ``flycrane plan``.

Artifacts are opened with their real readers (pymavlink's MAVWPLoader and parameter
reader, json, the mcap reader); the missions are checked end to end against the scene's
start and goal, and their speed items against the limits the plan solved.
"""

from __future__ import annotations

import errno
import json
import os
import re
from pathlib import Path

import numpy as np
import pytest
from mcap.reader import make_reader
from pymavlink import mavparm, mavwp

from flycrane.cli import main
from flycrane.errors import InputError
from flycrane.model.cable_system import CableSystem
from flycrane.model.kinematics import drone_positions_from_configuration
from flycrane.model.pose_error import height_bound
from flycrane.model.statics import evaluate_statics
from flycrane.planning.planners import PlannerOptions
from flycrane.planning.problem import PlanningProblem
from flycrane.planning.validity import InvalidConfigurationError
from flycrane.world.bodies import box_corners
from flycrane.world.scene import SCENES_DIR, load_scene
from missions.autopilots.ardupilot import ArduCopterSettings, team_parameters
from missions.autopilots.spline import SpeedLimits
from missions.export.formats import mission_from_json
from missions.export.items import MavCmd
from missions.options import MissionOptions
from missions.position_error import PRESETS
from missions.task.build import build
from missions.task.directory import TaskDirectory, TaskDirectoryError
from missions.task.pipeline import run_task
from missions.task.resolve import resolve_task
from missions.task.spec import TaskSpec, load_task
from missions.trajectory.motion import DroneMotion
from tests.missions.helpers import applied_limits, approximate_geodetic

TASK = TaskSpec(planner=PlannerOptions(seed=0, time_budget=60))


@pytest.fixture(scope="module")
def rescue(tmp_path_factory):
    out = tmp_path_factory.mktemp("rescue")
    return run_task(TASK, out), out


def test_default_rescue_task_is_done_with_every_artifact(rescue):
    outcome, out = rescue
    assert outcome.status == "done", outcome.reason
    assert outcome.planner_status == "exact_solution"
    expected = {"path.json", "tracks.json", "mission.mcap", "profile.png", "summary.json"}
    expected |= {"task.json"}
    expected |= {f"drone{j}.{kind}" for j in (1, 2, 3) for kind in
                 ("waypoints", "plan", "mission.json", "parm", "trajectory.csv")}  # fmt: skip
    assert set(outcome.artifacts.values()) == expected
    for name in expected:
        assert (out / name).stat().st_size > 0, name
    assert (out / "profile.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    summary = json.loads((out / "summary.json").read_text(encoding="utf-8"))
    assert summary["status"] == "done"
    assert summary["mission"] == json.loads(json.dumps(outcome.mission.as_dict()))
    assert 0.0 < summary["mission"]["timing_tolerance"]["start_offset"]


def test_a_run_that_ends_early_leaves_no_earlier_run_s_missions_beside_it(rescue, tmp_path):
    """A user re-plans into the directory of a finished task and the run is cancelled: the
    old missions must not stand beside the new summary as if they were its own."""
    _, done = rescue
    for path in done.iterdir():
        (tmp_path / path.name).write_bytes(path.read_bytes())
    (tmp_path / "notes.txt").write_text("mine", encoding="utf-8")
    outcome = run_task(TASK, tmp_path, should_stop=lambda: True)
    assert outcome.status == "cancelled"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["notes.txt", "summary.json"]
    assert json.loads((tmp_path / "summary.json").read_text(encoding="utf-8"))["status"] == (
        "cancelled"
    )


def test_an_interrupted_run_leaves_the_last_finished_run_whole(rescue, tmp_path, monkeypatch):
    """Interrupted while it writes (Ctrl-C in ``flycrane plan``), a run must not leave its
    task beside the last run's missions: the flight tools read both. Then the next run
    replaces the last one whole."""
    _, done = rescue
    for path in done.iterdir():
        (tmp_path / path.name).write_bytes(path.read_bytes())
    other = TaskSpec(name="other", scene="corridor", planner=PlannerOptions(seed=7))

    def interrupted(*_: object) -> None:
        raise KeyboardInterrupt

    monkeypatch.setattr("missions.task.pipeline.write_files", interrupted)
    with pytest.raises(KeyboardInterrupt):
        run_task(other, tmp_path)
    for path in done.iterdir():
        assert (tmp_path / path.name).read_bytes() == path.read_bytes(), path.name
    monkeypatch.undo()
    outcome = run_task(other, tmp_path)
    assert outcome.status == "done", outcome.reason
    assert TaskDirectory(tmp_path).task().name == "other"
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(p.name for p in done.iterdir())


def test_a_write_that_fails_names_its_file(tmp_path, monkeypatch):
    """A full disk fails the write, not the open, with an error that names no file."""

    def full(self: Path, *_: object, **__: object) -> None:
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

    directory = TaskDirectory(tmp_path).create()
    monkeypatch.setattr(Path, "write_text", full)
    with pytest.raises(OSError) as failed:
        directory.write_task(TASK)
    assert failed.value.errno == errno.ENOSPC
    assert str(failed.value).endswith(f"{tmp_path / '.partial' / 'task.json'}'")


def test_the_task_json_a_run_writes_plans_the_same_missions_again(rescue, tmp_path):
    """``task.json`` says what was planned: planned again it gives the same missions, its
    lift-off and set-down included (it used to hold the raised ends, and lost them)."""
    outcome, done = rescue
    again = run_task(TaskDirectory(done).task(), tmp_path)
    assert again.status == "done", again.reason
    assert again.mission.set_down is not None and outcome.mission.set_down is not None
    for k in (1, 2, 3):
        name = f"drone{k}.waypoints"
        assert (tmp_path / name).read_bytes() == (done / name).read_bytes(), name


def test_plan_refuses_to_write_over_the_task_file_it_reads(rescue, tmp_path, capsys):
    _, done = rescue
    for path in done.iterdir():
        (tmp_path / path.name).write_bytes(path.read_bytes())
    task = tmp_path / "task.json"
    assert main(["plan", str(task), "--out", str(tmp_path)]) == 2
    assert f"--out: {tmp_path} holds the task being planned" in capsys.readouterr().err
    assert task.read_bytes() == (done / "task.json").read_bytes()


def test_a_start_given_as_a_pose_takes_alphas_that_rise_clear_of_its_surface():
    """The Rescue's start as a platform pose: the least-cost alphas of the pose leave the
    drones a centimetre from the buildings, which the plan's clearance refuses once raised;
    the alphas taken are the least-cost ones that rise clear."""
    scene = load_scene("rescue")[0]
    pose = {"position": list(scene.start[:3]), "orientation": list(scene.start[3:6])}
    resolved = resolve_task(TaskSpec(start=pose))
    assert resolved.lift_off is not None
    np.testing.assert_allclose(resolved.lift_off.low[:6], scene.start[:6])
    assert resolved.checkers.planning.is_valid(resolved.start)[0]


def test_tracks_store_the_modelled_motions_at_the_rate_readers_need(rescue):
    """tracks.json scales with the mission's duration at 20 samples a second (issue 22,
    item 5: a 1 km task wrote 158 MB at the model's 100), and its motion read back by
    interpolation stays within 2 mm of the vehicles the waypoints' own model puts there."""
    outcome, out = rescue
    stored = json.loads((out / "tracks.json").read_text(encoding="utf-8"))
    duration = outcome.mission.duration
    for key in ("motion", "vehicle_motion"):
        time = np.array(stored[key]["time"])
        assert np.diff(time)[:-1] == pytest.approx(0.05, abs=1e-9)
        assert len(time) <= 20 * time[-1] + 2
    assert (out / "tracks.json").stat().st_size < 40_000 * duration
    path = np.array(json.loads((out / "path.json").read_text())["configurations"])
    full = build(resolve_task(TASK), path).tracks  # the model's 100 Hz samples
    for key, motion in (("motion", full.motion), ("vehicle_motion", full.vehicle_motion)):
        read = DroneMotion.from_dict(stored[key]).at(motion.time)
        assert np.linalg.norm(read - motion.drones, axis=-1).max() < 0.002, key


def test_rescue_files_load_with_their_readers_and_agree(rescue):
    outcome, out = rescue
    waypoints = outcome.mission.waypoints
    for j in (1, 2, 3):
        loader = mavwp.MAVWPLoader()
        count = loader.load(str(out / f"drone{j}.waypoints"))
        assert count == outcome.mission.items_per_drone[j - 1]
        commands = [loader.wp(i).command for i in range(count)]
        # home, then one spline waypoint per leg
        assert commands.count(MavCmd.NAV_WAYPOINT) == 1
        assert commands.count(MavCmd.NAV_SPLINE_WAYPOINT) == waypoints - 1
        mission = mission_from_json(json.loads((out / f"drone{j}.mission.json").read_text()))
        assert [int(it.command) for it in mission.items] == commands
        plan = json.loads((out / f"drone{j}.plan").read_text(encoding="utf-8"))
        assert len(plan["mission"]["items"]) == count - 1
    with (out / "mission.mcap").open("rb") as stream:
        reader = make_reader(stream)
        topics = {c.topic for c in reader.get_summary().channels.values()}
        assert {"/scene", "/tf", "/drone1/fix", "/annotations/cost"} <= topics
        assert sum(1 for _ in reader.iter_messages(topics=["/annotations/cost"])) == waypoints
    tracks = json.loads((out / "tracks.json").read_text(encoding="utf-8"))
    assert len(tracks["time"]) == len(tracks["drones_enu"]) == waypoints
    path = json.loads((out / "path.json").read_text(encoding="utf-8"))
    assert len(path["configurations"]) >= 2


def test_rescue_missions_hold_above_the_start_and_set_the_bridge_down_on_the_roofs(rescue):
    """The default position-error model (RTK) keeps 8 cm from everything; the scene's start
    (bridge 5 cm above the ground) is lifted by the take-off and its goal (5 cm above the
    roofs) is reached by a set-down onto both buildings."""
    outcome, out = rescue
    scene, _ = load_scene("rescue")
    system = CableSystem.from_spec(scene.system_spec())
    summary = outcome.mission.as_dict()
    assert summary["obstacle_clearance"] == pytest.approx(0.08)
    assert summary["lift_off"]["surfaces"] == ["ground"]
    assert summary["set_down"]["surfaces"] == ["east building", "west building"]
    # the set-down starts set_down_approach above the lowest clear pose: the bridge 5 cm
    # above the roofs needs 3 cm more for 8 cm of clearance
    approach = MissionOptions().set_down_approach
    assert summary["set_down"]["height"] == pytest.approx(0.03 + approach, abs=0.011)
    # the start is lifted to the lowest pose 8 cm clear (5 cm above the ground needs 3 cm
    # more), and then by what the bound of the model's errors at the hold asks beyond that
    model = PRESETS["rtk"]
    checker = PlanningProblem.from_scene(scene).validity.collision
    corners = np.concatenate([box_corners(b) for b in checker.platform_fixed])
    bound = height_bound(system, scene.start, corners, model.common_vertical, model.own).max()
    assert bound > 0.08
    lift = summary["lift_off"]["height"]
    assert lift == pytest.approx(0.03 + bound - 0.08, abs=0.011)
    raised = np.array(scene.start) + [0, 0, lift, 0, 0, 0, 0, 0, 0]
    ends = drone_positions_from_configuration(system, [raised, scene.goal])
    origin = MissionOptions().origin
    for j in (1, 2, 3):
        items = mission_from_json(json.loads((out / f"drone{j}.mission.json").read_text())).items
        hold, last = items[2], [it for it in items if it.command == MavCmd.NAV_SPLINE_WAYPOINT][-1]
        assert hold.command == MavCmd.NAV_LOITER_UNLIM
        for item, enu in ((hold, ends[0][j - 1]), (last, ends[1][j - 1])):
            lat, lon = approximate_geodetic(enu, origin)
            assert abs(item.x - lat * 1e7) <= 0.51 and abs(item.y - lon * 1e7) <= 0.51
            # stored in whole centimetres, above home: where the drone stood
            assert item.z + MissionOptions().home_height == pytest.approx(enu[2], abs=0.01)


def test_rescue_speed_items_are_the_limits_the_plan_solved(rescue):
    _, out = rescue
    tracks = json.loads((out / "tracks.json").read_text(encoding="utf-8"))
    initial = ArduCopterSettings().initial_speeds
    for j in (1, 2, 3):
        mission = mission_from_json(json.loads((out / f"drone{j}.mission.json").read_text()))
        planned = [SpeedLimits(**limits) for limits in tracks["speed_limits"][j - 1]]
        assert applied_limits(mission, initial) == planned


def test_rescue_parameter_files_read_with_pymavlink_say_what_the_plan_assumes(rescue):
    _, out = rescue
    for j in (1, 2, 3):
        read = mavparm.MAVParmDict()
        read.load(str(out / f"drone{j}.parm"), use_excludes=False)
        expected = ArduCopterSettings.for_acceleration(MissionOptions().autopilot_acceleration)
        team, _ = team_parameters("gnss")  # the default model's (rtk) height source
        assert dict(read) == pytest.approx({**expected.parameters(), **team})
        assert "BARO_GND_TEMP" not in read  # never changed on a powered vehicle


def test_a_start_in_collision_is_refused_naming_the_bodies():
    on_the_ground = (0.0, 0.0, 0.2, 0.0, 0.0, np.pi / 2, 1.0, 1.0, 1.0)  # bridge 0.2 m too low
    with pytest.raises(InvalidConfigurationError) as caught:
        resolve_task(TaskSpec(start=on_the_ground))
    assert caught.value.what == "start"
    assert ("footbridge", "ground") in {(c.body, c.other) for c in caught.value.reason.contacts}
    assert "footbridge hits ground" in str(caught.value)


def test_a_goal_inside_a_building_names_the_building():
    with pytest.raises(InvalidConfigurationError) as caught:
        resolve_task(TaskSpec(goal=(-6.0, 0.0, 4.0, 0.0, 0.0, 0.0, 1.0, 1.0, 1.0)))
    assert caught.value.what == "goal"
    assert {c.other for c in caught.value.reason.contacts} == {"west building"}


def test_an_unknown_scene_is_an_input_error_naming_the_scene_field():
    with pytest.raises(InputError) as caught:
        resolve_task(TaskSpec(scene="atlantis"))
    assert [p.field for p in caught.value.problems] == ["scene"]
    assert "atlantis" in str(caught.value) and "rescue" in str(caught.value)


def box_mesh(name: str, center: list[float], size: list[float]) -> dict:
    """A box as a named triangle mesh (12 faces), as a site from CAD would give it."""
    x, y, z = (v / 2 for v in size)
    vertices = [[sx * x, sy * y, sz * z] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)]
    faces = [[0, 1, 3], [0, 3, 2], [4, 6, 7], [4, 7, 5], [0, 4, 5], [0, 5, 1],
             [2, 3, 7], [2, 7, 6], [0, 2, 6], [0, 6, 4], [1, 5, 7], [1, 7, 3]]  # fmt: skip
    return {"kind": "mesh", "name": name, "center": center, "vertices": vertices, "faces": faces}


def test_the_rescue_with_its_buildings_as_meshes_plans_with_the_default_mission(tmp_path):
    """Issue 24: the Rescue's buildings given as triangle meshes (12 faces each, the same
    boxes) with the default position-error model's clearance: planned by bitrrt, the
    missions made, the bridge set down onto both roofs, as with boxes."""
    scene = load_scene("rescue")[0].model_dump(mode="json")
    scene["obstacles"] = [box_mesh(o["name"], o["center"], o["size"]) for o in scene["obstacles"]]
    task = TaskSpec(scene=scene, planner=PlannerOptions(seed=0, time_budget=60))
    resolved = resolve_task(task)
    assert resolved.algorithm == "bitrrt" and not resolved.problem.validity.payload_meshes
    outcome = run_task(task, tmp_path)
    assert outcome.status == "done", outcome.reason
    mission = outcome.mission
    assert mission.obstacle_clearance == pytest.approx(0.08)
    assert set(mission.set_down.leg.surfaces) == {"west building", "east building"}


def test_a_task_of_mesh_files_plans_again_from_its_directory_alone(tmp_path, monkeypatch):
    """The mesh files a scene names are copied into the task's directory and task.json
    names the copies: planned again from elsewhere it gives the same missions (task.json
    named the files relative to the task file's folder, and nothing could read them)."""
    site = tmp_path / "site"
    site.mkdir()
    scene = load_scene("rescue")[0].model_dump(mode="json")
    for k, obstacle in enumerate(scene["obstacles"]):
        mesh = box_mesh(obstacle["name"], obstacle["center"], obstacle["size"])
        lines = [f"v {x} {y} {z}" for x, y, z in mesh["vertices"]]
        lines += [f"f {a + 1} {b + 1} {c + 1}" for a, b, c in mesh["faces"]]
        (site / f"building{k}.OBJ").write_text("\n".join(lines) + "\n")
        scene["obstacles"][k] = {**mesh, "file": f"building{k}.OBJ", "vertices": None,
                                 "faces": None}  # fmt: skip
    (site / "task.json").write_text(json.dumps({"scene": scene, "planner": {"seed": 0}}))
    assert main(["plan", str(site / "task.json"), "--out", str(tmp_path / "out")]) == 0
    out = tmp_path / "out"
    written = TaskDirectory(out).task().scene.obstacles
    assert [o.file for o in written] == ["mesh1.obj", "mesh2.obj"]
    for k in (0, 1):
        assert (out / f"mesh{k + 1}.obj").read_bytes() == (site / f"building{k}.OBJ").read_bytes()
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    monkeypatch.chdir(elsewhere)
    assert main(["plan", "../out/task.json", "--out", "again"]) == 0
    for name in ("drone1.waypoints", "drone2.waypoints", "drone3.waypoints"):
        assert (elsewhere / "again" / name).read_bytes() == (out / name).read_bytes(), name
    (elsewhere / "again" / "mesh2.obj").unlink()  # a copy without its meshes is named
    with pytest.raises(TaskDirectoryError, match=r"mesh2\.obj is missing .*'east building'"):
        TaskDirectory(elsewhere / "again").task()
    assert main(["plan", "--out", str(out)]) == 0  # the default Rescue, of boxes
    assert not list(out.glob("mesh*"))


def test_a_task_file_s_scene_path_is_relative_to_the_task_file(tmp_path, monkeypatch):
    """It was relative to where the command ran: a task file beside its scene, planned
    from anywhere else, had 'no scene'."""
    site = tmp_path / "site"
    site.mkdir()
    (site / "scene.toml").write_text((SCENES_DIR / "rescue.toml").read_text())
    (site / "task.json").write_text(json.dumps({"scene": "scene.toml"}))
    monkeypatch.chdir(tmp_path)
    resolved = resolve_task(*load_task(site / "task.json"))
    assert resolved.problem.scene.obstacles == load_scene("rescue")[0].obstacles


def test_bitrrt_asked_for_with_a_mesh_payload_is_refused_naming_the_field():
    """bitrrt checks a payload of primitive shapes only: asked for with a mesh payload it is
    refused at once; the default falls back to T-RRT (flycrane/planning/planners.py)."""
    scene = load_scene("rescue")[0].model_dump(mode="json")
    scene["payload"]["shapes"] = [box_mesh("footbridge", [0.0, 0.0, -0.35], [4.6, 0.8, 0.1])]
    with pytest.raises(InputError) as caught:
        resolve_task(TaskSpec(scene=scene, planner=PlannerOptions(algorithm="bitrrt")))
    assert [p.field for p in caught.value.problems] == ["planner.algorithm"]
    assert "trrt" in str(caught.value)
    resolved = resolve_task(TaskSpec(scene=scene))
    assert resolved.problem.validity.payload_meshes
    # task.json names the planner, and reads back as a task (the flight report's)
    written = resolved.self_contained().model_dump(mode="json")
    assert written["planner"]["algorithm"] == "trrt"
    resolve_task(TaskSpec.model_validate(written))


def test_plan_command_prints_where_the_missions_are(tmp_path, capsys):
    assert main(["plan", "--out", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    assert "status: done" in out
    for j in (1, 2, 3):
        assert str(tmp_path / f"drone{j}.waypoints") in out
        assert (tmp_path / f"drone{j}.waypoints").exists()
    assert str(tmp_path / "mission.mcap") in out
    assert str(tmp_path / "summary.json") in out
    # the default model's clearance, and the robust margin the default requires
    assert re.search(r"clearance kept: 8\.0 cm; robust margin \d+\.\d cm\n", out), out


def test_a_robust_clearance_plans_again_until_the_errors_cannot_close_the_gap(tmp_path, capsys):
    """``mission.robust_clearance`` on the Puzzle (``sitl`` model), through ``flycrane
    plan``: its first path passes the slab where the drones' errors could close more than
    the 7 cm it keeps, so it is planned again keeping more; the path built keeps that
    clearance (fcl along it, at the checker's resolution) and a robust margin of zero or
    more, and the command says so."""
    mission = {"position_error": "sitl", "robust_clearance": True}
    task_file, out = tmp_path / "task.in.json", tmp_path / "out"
    spec = {"scene": "puzzle", "planner": {"seed": 1}, "mission": mission}
    task_file.write_text(json.dumps(spec))
    assert main(["plan", str(task_file), "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    written = json.loads((out / "summary.json").read_text())
    raised = [a for a in written["attempts"] if "clearance" in a]
    assert raised and "robust margin -0.0" in raised[0]["reason"]
    summary = written["mission"]
    assert summary["obstacle_clearance"] == pytest.approx(raised[-1]["clearance"])
    assert summary["obstacle_clearance"] > PRESETS["sitl"].obstacle_clearance + 0.02
    assert summary["robust_margin"] >= 0.0
    assert f"planned again keeping {raised[-1]['clearance']:.3f} m" in printed
    assert f"robust margin {100 * summary['robust_margin']:.1f} cm" in printed
    assert summary["robust_statics_margin"] >= 0.0
    assert (f"least {summary['robust_statics_margin']:.2f} N "
            f"({summary['robust_statics_limit']})") in printed  # fmt: skip
    task = json.loads((out / "task.json").read_text())
    assert task["scene"]["collision"]["obstacle_clearance"] == summary["obstacle_clearance"]
    problem = PlanningProblem.from_scene(load_scene("puzzle")[0])
    checker = problem.validity.with_clearance(summary["obstacle_clearance"])
    path = json.loads((out / "path.json").read_text())["configurations"]
    samples = problem.space.discretize_path(np.array(path), checker.resolution)
    assert checker.collision.collision_free(samples).all()


def test_the_default_task_requires_a_robust_margin_and_can_be_told_not_to(rescue, tmp_path):
    """``mission.robust_clearance`` is on by default: the summary gives the path's robust
    margin, at least zero on the Rescue; a task that turns it off keeps one clearance and
    reports none."""
    _, out = rescue
    assert json.loads((out / "summary.json").read_text())["mission"]["robust_margin"] >= 0.0
    task = TASK.model_copy(update={"mission": MissionOptions(robust_clearance=False)})
    assert run_task(task, tmp_path).status == "done"
    assert "robust_margin" not in json.loads((tmp_path / "summary.json").read_text())["mission"]


def test_the_statics_margins_are_reported_against_the_drones_errors(rescue):
    """Every summary gives the path's least statics margin less what the model's drone
    errors can take of it: below the path's least plain margin (statics of the path's
    samples), by no more than the bound's worst, and above zero on the default Rescue
    (its margins, 1.4 N, are far beyond what 3 cm of error takes)."""
    _, out = rescue
    summary = json.loads((out / "summary.json").read_text())["mission"]
    problem = PlanningProblem.from_scene(load_scene("rescue")[0])
    path = np.array(json.loads((out / "path.json").read_text())["configurations"])
    report = evaluate_statics(problem.system, problem.space.discretize_path(path, 0.05))
    least = min(report.slack_margin.min(), report.overload_margin.min(),
                report.thrust_margin.min())  # fmt: skip
    assert 0.0 < summary["robust_statics_margin"] < least
    assert least - summary["robust_statics_margin"] < 0.5
    kind, _, _, number = summary["robust_statics_limit"].split(" ")
    assert kind in ("slack", "overload", "thrust") and 1 <= int(number) <= 6
