"""Playing the plan from one clock on three ArduCopter 4.5.7 SITL autopilots: in step, a team
that stops together under injected faults, an onboard player that keeps the clock through a
lost link, and the positioning the plan assumes enforced before the release.

Evidence independent of the executors: the simulators' true positions (SIM_STATE) and their
own clocks (SYSTEM_TIME, one epoch for the three), read from the tlogs by the flight report,
which rebuilds the load from the three drones and judges it on the real obstacles. The
thresholds are issue 23's targets where the flights meet them with a margin, and otherwise
the bounds BENCHMARKS.md reports ("Execution in step") with the targets they miss.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from pymavlink import mavutil

from tests.missions.sitl.flights import CLOSE_SPEEDUP, SITL_MARKS, fly, plan, run_fly_sitl

pytestmark = SITL_MARKS


def assert_in_step(report: dict, duration: float = 0.02, start: float = 0.05) -> None:
    """The drones flew the plan together on one clock (true positions judged)."""
    true, estimated = report["true"], report["estimated"]
    assert report["verdict"]["safe"], report["verdict"]["reasons"]
    assert true["pair_error_common_p95"] <= 0.05, true["pair_error_common_p95"]
    assert estimated["pair_error_common_p95"] <= 0.035, estimated["pair_error_common_p95"]
    assert max(estimated["error_in_time_p95"]) <= 0.05, estimated["error_in_time_p95"]
    # least true clearances over 10 flights per scene and mode, of the `sitl` model's 7 cm:
    # the Rescue 5.9-10.3 cm since its raised ends keep the error bound, the Puzzle's bar
    # by the slab 4.8 cm at worst (BENCHMARKS.md, "The holds keep the bound")
    assert true["least_clearance"] >= 0.045, true["least_clearance_bodies"]
    assert report["timing"]["start_spread"] <= start, report["timing"]["start_spread"]
    assert report["timing"]["progress_spread_p95"] <= 0.1
    flown, planned = report["timing"]["flown_duration"], report["planned_duration"]
    assert abs(flown / planned - 1.0) <= duration, (flown, planned)


def execution(out: Path) -> dict:
    return json.loads((out / "execution.json").read_text())


def test_the_rescue_streamed_from_one_clock_flies_in_step(rescue: Path, tmp_path: Path):
    """And the estimates the report judges are recorded at the harness's 50 Hz through the
    flight (a readiness check that asked for 5 Hz once left them there); and the three
    simulators' clocks agree through it, as GNSS time does for real drones (each one's
    time against the tlog's receipt times, which run at the simulators' pace). Brought
    together before the release, they stayed within 4.4 ms over 40 flights on one 2-core
    host and 21 ms in one flight on another, whose simulators' paces wander by tens of ms
    over seconds; left apart, they were 40 ms at the median (BENCHMARKS.md, "The recorded
    estimates, a faster boot and the simulators' clocks")."""
    report = fly(rescue, tmp_path, "--mode", "stream", speedup=CLOSE_SPEEDUP)
    assert_in_step(report)
    assert report["stop"] is None and execution(tmp_path)["faults"] == []
    behind = []
    for k in (1, 2, 3):
        log = mavutil.mavlink_connection(str(tmp_path / f"drone{k}.tlog"))
        times = []
        while msg := log.recv_match(type=["GLOBAL_POSITION_INT", "POSITION_TARGET_LOCAL_NED"]):
            times.append((msg.get_type(), msg.time_boot_ms / 1000.0, msg._timestamp))
        first = min(t for kind, t, _ in times if kind == "POSITION_TARGET_LOCAL_NED")
        flown = [(t, r) for kind, t, r in times if kind == "GLOBAL_POSITION_INT" and t >= first]
        assert len(flown) >= 0.9 * 50 * (flown[-1][0] - flown[0][0]), (k, len(flown))
        behind.append(float(np.median([r - t for t, r in flown])))
    assert max(behind) - min(behind) <= 0.03, behind


def test_the_puzzle_streamed_from_one_clock_flies_in_step(puzzle: Path, tmp_path: Path):
    """The Puzzle's starts spread 11 ms at the median and 20 ms at worst over 10 flights
    since the 3 s hand-over (BENCHMARKS.md, "Execution in step", "Third run"), and 32 ms
    once in a suite run: the spread moves by a player's or a stream's tick between flights
    of the same plan, so the test holds 50 ms and the benchmark the 20 ms target. Flown at
    :data:`CLOSE_SPEEDUP`: at x5 its progress spread and tracking left their bounds in two
    of four runs."""
    assert_in_step(fly(puzzle, tmp_path, "--mode", "stream", speedup=CLOSE_SPEEDUP))


def test_a_late_drone_slows_the_team_instead_of_stretching_the_formation(
    rescue: Path, tmp_path: Path
):
    """Drone 3 held at its start for 1 s after the others' start: the group clock falls
    (the plan waits for it) and the formation holds."""
    report = fly(
        rescue, tmp_path, "--mode", "stream", "--fault", "late:3:0:1.0", speedup=CLOSE_SPEEDUP
    )
    record = execution(tmp_path)
    assert min(s["rate_end"] for s in record["segments"]) < 0.5  # the team waited
    assert report["verdict"]["safe"], report["verdict"]["reasons"]
    assert report["true"]["pair_error_common_max"] <= 0.1


@pytest.mark.parametrize("fault", ["gps:2:8", "link:1:6", "mode:3:10"])
def test_a_fault_stops_the_three_together_and_the_load_stays_safe(
    rescue: Path, tmp_path: Path, fault: str
):
    """One drone's GNSS lost, its link lost, or its mode switched to BRAKE mid-flight: the
    team stop goes out within a second of the fault (a lost link is only seen by its
    silence), the two healthy drones are at rest within 1 s of it, and the load is safe
    through the stop and the hold after it (true positions). Flown at
    :data:`CLOSE_SPEEDUP`: at x5 the mode switch's healthy drones once came to rest 2.75 s
    after the stop."""
    report = fly(rescue, tmp_path, "--mode", "stream", "--fault", fault, speedup=CLOSE_SPEEDUP)
    assert report["verdict"]["safe"], report["verdict"]["reasons"]
    stop = report["stop"]
    assert stop is not None
    assert stop["detected_after"] <= 1.0, stop
    faulty = int(fault.split(":")[1]) - 1
    healthy = [s for k, s in enumerate(stop["at_rest_after"]) if k != faulty]
    assert max(healthy) <= 1.0, stop


def test_a_weak_motor_is_seen_by_its_attitude_and_the_team_stops_safely(
    rescue: Path, tmp_path: Path
):
    """Drone 2's motor at 0.8 of its thrust mid-flight: the drone tilts away from the
    attitude its own controller asks for before it strays from its target, and the team
    stops on that; the load is safe through the stop (true positions)."""
    report = fly(
        rescue, tmp_path, "--mode", "stream", "--fault", "motor:2:5.7:0.8", speedup=CLOSE_SPEEDUP
    )
    assert report["verdict"]["safe"], report["verdict"]["reasons"]
    first = execution(tmp_path)["faults"][0]
    assert (first["drone"], first["kind"]) == (2, "attitude"), first
    stop = report["stop"]
    assert stop["detected_after"] <= 1.0, stop
    assert max(stop["at_rest_after"][0], stop["at_rest_after"][2]) <= 1.0, stop


def test_a_weak_motor_whose_drone_swings_away_is_followed_as_far_as_keeps_the_load_safe(
    tmp_path: Path,
):
    """The Puzzle's seed 5, drone 3's motor at 0.8 of its thrust: the drone swings half
    a metre east of its stop. Braked where they were, or moved only as far as kept the
    load feasible, the other two let a cable go slack (5 of 5 runs, BENCHMARKS.md "A weak
    motor"); moved with it as far as keeps the load safe with room to spare and pushed by
    its lean, they follow it by more than 0.3 m and the load stays safe (true
    positions). Flown on the plan kept at one clearance, where the rule was measured: the
    robust plan of this seed keeps a robust statics margin of 0.001 N, and lost a cable by
    9 mN in one of five suite runs (BENCHMARKS.md "The missions mode on robust plans")."""
    task_dir = plan("puzzle", 5, tmp_path / "plan", robust_clearance=False)
    out = tmp_path / "flight"
    report = fly(
        task_dir, out, "--mode", "stream", "--fault", "motor:3:8.6:0.8", speedup=CLOSE_SPEEDUP
    )
    assert report["verdict"]["safe"], report["verdict"]["reasons"]
    assert (execution(out)["faults"][0]["kind"], execution(out)["faults"][0]["drone"]) == (
        "attitude",
        3,
    )
    flown = json.loads((out / "flown.json").read_text())
    time, drones = np.array(flown["time"]), np.array(flown["drones_enu"])
    stop = int(np.argmin(abs(time - report["stop"]["commanded_at"])))
    moved = np.linalg.norm(drones[stop:] - drones[stop], axis=-1).max(axis=0)
    assert moved[2] > 0.3 and min(moved[0], moved[1]) > 0.3, moved


def test_the_onboard_player_keeps_the_team_in_step_through_a_lost_link(
    rescue: Path, tmp_path: Path
):
    """The players on board keep the group clock: drone 1's link lost mid-flight, all
    three fly on in step to the end, with no team stop."""
    report = fly(
        rescue, tmp_path, "--mode", "onboard", "--fault", "link:1:6", speedup=CLOSE_SPEEDUP
    )
    assert report["stop"] is None
    assert [f["kind"] for f in execution(tmp_path)["faults"]] == ["link"]
    assert report["verdict"]["safe"], report["verdict"]["reasons"]
    assert report["true"]["pair_error_common_p95"] <= 0.05
    flown, planned = report["timing"]["flown_duration"], report["planned_duration"]
    assert abs(flown / planned - 1.0) <= 0.05


def test_stock_sensors_fly_safely_with_the_positioning_of_the_plan(rescue: Path, tmp_path: Path):
    """SITL's sensors as they come (no barometer calibration, gyro drift on): the .parm's
    GNSS height makes the flight the plan assumes."""
    report = fly(rescue, tmp_path, "--stock-sensors")
    assert report["verdict"]["safe"], report["verdict"]["reasons"]


def test_stock_sensors_on_barometric_height_are_refused_the_release(rescue: Path, tmp_path: Path):
    """The same drones left on the barometer (the parameter a user forgot): the release is
    refused on the ground, naming the height source and the drones, and none takes off
    (their own altitude estimates, from the tlogs)."""
    done = run_fly_sitl(rescue, tmp_path, "--stock-sensors", "--parameter", "EK3_SRC1_POSZ=1")
    assert done.returncode == 3, done.stderr[-3000:]
    assert "release refused" in done.stdout and "EK3_SRC1_POSZ" in done.stdout
    flight = json.loads((tmp_path / "flight.json").read_text())
    assert {r.split(" ")[1] for r in flight["refused"] if "EK3_SRC1_POSZ" in r} == {"1", "2", "3"}
    assert not (tmp_path / "report.json").exists()
    for k in (1, 2, 3):
        log = mavutil.mavlink_connection(str(tmp_path / f"drone{k}.tlog"))
        heights = []
        while (msg := log.recv_match(type="GLOBAL_POSITION_INT")) is not None:
            heights.append(msg.relative_alt / 1000.0)
        assert heights and max(heights) < 0.5, (k, max(heights, default=None))
