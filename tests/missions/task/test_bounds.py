"""Every phase of a task's mission work is bounded (issue 22, item 4): a task that cannot fit
the longest mission is refused before it is planned, a path that cannot is failed before
its missions are built, the making stops at its time budget, and a cancel reaches it.
(How memory and time grow with the duration up to the bound: benchmarks/mission_bounds.py,
BENCHMARKS.md "Bounded work".)"""

from __future__ import annotations

import json
import time
import tracemalloc
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from flycrane.errors import InputError
from flycrane.planning.planners import PlannerOptions
from missions.options import MAX_MISSION_DURATION_S, MissionOptions
from missions.task.build import UnflyablePath, build
from missions.task.documents import raised_clearance
from missions.task.limits import Cancelled, MissionFailure, PhaseLimits
from missions.task.pipeline import run_task
from missions.task.resolve import resolve_task
from missions.task.spec import TaskSpec

LEVEL = [0.0, 0.0, 0.0, 1.0, 1.0, 1.0]  # phi theta sigma alpha1-3


def field_task(start_x: float, goal_x: float, speed: float = 0.5) -> TaskSpec:
    """An open field 18 km long: the platform 3 m up, moved along x."""
    scene = {
        "name": "field",
        "ground": True,
        "obstacles": [],
        "bounds": {"position_low": [-9500, -50, 0], "position_high": [9500, 50, 20]},
        "start": [start_x, 0.0, 3.0, *LEVEL],
        "goal": [goal_x, 0.0, 3.0, *LEVEL],
    }
    return TaskSpec.model_validate(
        {"scene": scene, "mission": {"max_drone_speed": speed, "position_error": "exact"}}
    )


@pytest.mark.parametrize(("length", "speed"), [(18_000.0, 0.05), (2_000.0, 0.5)])
def test_a_move_that_cannot_fit_the_longest_mission_is_refused_before_planning(length, speed):
    """The issue's 20 km at 0.05 m/s (a worker grew to 7.3 GB) and 2 km at 0.5 m/s."""
    task = field_task(-length / 2, length / 2, speed)
    with pytest.raises(InputError) as refused:
        resolve_task(task)
    (problem,) = refused.value.problems
    assert problem.field == "mission.max_drone_speed"
    assert f"{length / speed:.0f} s" in problem.reason  # the drones' straight travel
    assert f"{MAX_MISSION_DURATION_S:.0f} s a mission may last" in problem.reason


def test_a_path_that_cannot_fit_is_failed_before_its_missions_are_built():
    """Start and goal 10 m apart, the path out 1 km and back: refused by its waypoints,
    before anything is sampled (a few megabytes at most)."""
    resolved = resolve_task(field_task(-5.0, 5.0))
    detour = resolved.start.copy()
    detour[0] = 1000.0
    path = np.stack([resolved.start, detour, resolved.goal])
    tracemalloc.start()
    try:
        with pytest.raises(MissionFailure, match=r"would last at least 40\d\d s"):
            build(resolved, path)
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert peak < 5e6


def test_a_move_within_the_longest_mission_is_accepted():
    resolved = resolve_task(field_task(0.0, 0.9 * MAX_MISSION_DURATION_S * 0.5, 0.5))
    assert resolved.algorithm == "bitrrt"


def test_the_making_stops_at_its_time_budget():
    """Past the deadline the building fails naming the budget (the service's
    MAX_TIME_BUDGET=5 did not bound a 2 km mission's 66.8 s of making)."""
    resolved = resolve_task(field_task(0.0, 10.0))
    path = np.stack([resolved.start, resolved.goal])
    late = PhaseLimits(deadline=time.monotonic() - 1.0, budget=5.0)
    with pytest.raises(MissionFailure, match=r"longer than its time budget, 5 s \(planner"):
        build(resolved, path, late)


def test_a_task_whose_making_runs_out_of_time_fails_with_the_reason(tmp_path, monkeypatch):
    monkeypatch.setattr(
        PhaseLimits, "starting_now",
        classmethod(lambda cls, stop, budget: cls(stop, time.monotonic() - 1.0, budget)),
    )  # fmt: skip
    outcome = run_task(field_task(0.0, 10.0), tmp_path)
    assert outcome.status == "failed"
    assert outcome.reason.startswith("mission generation: it took longer than its time budget")


def test_a_cancel_reaches_the_mission_building(tmp_path: Path):
    """Cancelled once the planner is done: the task ends ``cancelled`` from inside the
    building, not after it."""
    task = TaskSpec(scene="rescue", planner=PlannerOptions(seed=0),
                    mission=MissionOptions(position_error="sitl"))  # fmt: skip
    stages: list[str] = []
    outcome = run_task(
        task,
        tmp_path,
        progress=lambda stage, _: stages.append(stage),
        should_stop=lambda: "generating" in stages,
    )
    assert outcome.status == "cancelled"
    assert outcome.reason == "cancelled while its missions were built"
    assert not (tmp_path / "tracks.json").exists()


def test_the_building_phases_raise_cancelled_when_asked():
    resolved = resolve_task(field_task(0.0, 10.0))
    path = np.stack([resolved.start, resolved.goal])
    with pytest.raises(Cancelled):
        build(resolved, path, PhaseLimits(should_stop=lambda: True))


def test_a_path_whose_missions_fail_their_check_is_planned_again_with_the_next_seed(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
):
    """Issue 24, item 5 (the Puzzle's seed 57 planned, then failed its mission check): the
    task plans again with the next seed, says what it tried, and task.json names the seed
    whose missions were made. The first path's check is made to fail here."""
    import missions.task.pipeline as pipeline

    calls: list[int] = []
    real_build = pipeline.build

    def failing_once(resolved, path, *robustness):  # type: ignore[no-untyped-def]
        calls.append(1)
        if len(calls) == 1:
            raise UnflyablePath("the modelled flight fails its check at 11.80 s")
        return real_build(resolved, path, *robustness)

    monkeypatch.setattr(pipeline, "build", failing_once)
    task = TaskSpec(scene="rescue", planner=PlannerOptions(seed=7),
                    mission=MissionOptions(position_error="sitl"))  # fmt: skip
    outcome = run_task(task, tmp_path)
    assert outcome.status == "done", outcome.reason
    # (the robust clearance may raise the clearance first: an attempt of its own)
    unflyable = tuple(a for a in outcome.attempts if not raised_clearance(a))
    assert unflyable == ({"seed": 7, "reason": "the modelled flight fails its check at "
                          "11.80 s"},)  # fmt: skip
    written = json.loads((tmp_path / "task.json").read_text())
    assert written["planner"]["seed"] == 8
    assert [a["seed"] for a in json.loads((tmp_path / "summary.json").read_text())["attempts"]
            if not raised_clearance(a)] == [7]  # fmt: skip


def test_a_path_the_drones_errors_could_make_infeasible_is_planned_again_when_asked(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
):
    """``mission.robust_clearance``: a path whose robust statics margin is below zero (made
    so here, for the first path) is planned again with the next seed, and the attempt says
    which margin fell short."""
    from missions.task.resolve import ResolvedTask

    calls: list[int] = []
    real = ResolvedTask.robust_statics

    def short_once(self, path):  # type: ignore[no-untyped-def]
        calls.append(1)
        statics = real(self, path)
        if len(calls) == 1:
            return replace(statics, bound=statics.bound + 100.0)
        return statics

    monkeypatch.setattr(ResolvedTask, "robust_statics", short_once)
    mission = MissionOptions(position_error="sitl", robust_clearance=True)
    task = TaskSpec(scene="rescue", planner=PlannerOptions(seed=7), mission=mission)
    outcome = run_task(task, tmp_path)
    assert outcome.status == "done", outcome.reason
    (attempt,) = [a for a in outcome.attempts if not raised_clearance(a)]
    assert attempt["seed"] == 7 and "robust statics margin -9" in attempt["reason"]
    assert attempt["reason"].split("(")[1].split(" ")[0] in ("slack", "overload", "thrust")
    assert json.loads((tmp_path / "task.json").read_text())["planner"]["seed"] == 8
    assert outcome.mission is not None and outcome.mission.robust_statics_margin > 0


def test_planning_again_stops_at_the_most_plans_and_says_which_seeds(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
):
    import missions.task.pipeline as pipeline

    def never(resolved, path, *robustness):  # type: ignore[no-untyped-def]
        raise UnflyablePath("no flyable plan")

    monkeypatch.setattr(pipeline, "build", never)
    outcome = run_task(TaskSpec(scene="rescue", planner=PlannerOptions(seed=3)), tmp_path)
    assert outcome.status == "failed"
    given_up = [a["seed"] for a in outcome.attempts if not raised_clearance(a)]
    assert given_up == [3, 4, 5, 6][: pipeline.MAX_PLANS]
    assert outcome.reason.endswith("(seeds tried: 3, 4, 5, 6)")
