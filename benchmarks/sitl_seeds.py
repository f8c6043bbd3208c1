"""Fly many seeds' missions of planner variants on three ArduCopter SITL autopilots, one
flight each, and compare the variants' flights.

    .venv/bin/python benchmarks/sitl_seeds.py --scenes puzzle rescue --seeds 0-29 \\
        --variant default '{}' --variant trrt '{"algorithm": "trrt"}' --out sitl-seeds

Each (scene, variant, seed) is planned by ``flycrane plan`` (the variant's fields are the
task's ``planner`` options, with ``mission.position_error`` set to ``--position-error``),
then flown by ``flycrane fly-sitl`` (its own private network namespace, simulators stopped
by PID). One row per task: the mission's timing tolerance, then the flight's verdict and
true-position figures; then per scene and variant the missions generated, the unsafe
flights, the least true clearance (median and worst) and the true inter-drone error p95
(median and worst). BENCHMARKS.md ("Planner v2, the default") records the runs.
"""

from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import sys
from pathlib import Path


def seeds(text: str) -> list[int]:
    """``0-29`` or ``3,5,8``; an argparse type, so a range that holds no seed (``5-2``) is
    refused as a bad argument rather than run as no runs at all."""
    if "-" in text:
        first, last = (int(x) for x in text.split("-"))
        if first > last:
            raise argparse.ArgumentTypeError(
                f"{text!r} holds no seed: FIRST-LAST needs FIRST <= LAST (e.g. 0-19)"
            )
        return list(range(first, last + 1))
    return [int(x) for x in text.split(",")]


def flycrane(*args: str) -> subprocess.CompletedProcess:
    command = [sys.executable, "-m", "flycrane.cli", *args]
    return subprocess.run(command, capture_output=True, text=True, timeout=1800)


def run(scene: str, fields: dict, seed: int, error: str, out: Path, resume: bool) -> dict:
    """Plan and fly one task; what its summary and flight report say. With ``resume``, a
    plan or flight already in ``out`` for the same task is read instead of made again."""
    out.mkdir(parents=True, exist_ok=True)
    task = {"scene": scene, "planner": {**fields, "seed": seed},
            "mission": {"position_error": error}}  # fmt: skip
    task_file, summary_file = out / "task.in.json", out / "plan" / "summary.json"
    report_file = out / "flight" / "report.json"
    same = resume and task_file.exists() and json.loads(task_file.read_text()) == task
    if not (same and summary_file.exists()):
        task_file.write_text(json.dumps(task))
        report_file.unlink(missing_ok=True)
        flycrane("plan", str(task_file), "--out", str(out / "plan"))
    summary = json.loads(summary_file.read_text())
    if summary["status"] != "done":
        return {"mission": False, "reason": summary["reason"]}
    tolerance = summary["mission"]["timing_tolerance"]
    if not report_file.exists():
        flown = flycrane("fly-sitl", str(out / "plan"), "--out", str(out / "flight"))
        if not report_file.exists():
            return {"mission": True, "flown": False, "reason": flown.stderr[-500:]}
    report = json.loads(report_file.read_text())
    true = report["true"] or report["estimated"]
    return {
        "mission": True,
        "flown": True,
        "tolerance": (tolerance["start_offset"], tolerance["speed_mismatch"]),
        "safe": report["verdict"]["safe"],
        "reasons": report["verdict"]["reasons"],
        "clearance": true["least_clearance"],
        "inter_drone_p95": true["inter_drone_error_p95"],
        "spread_p95": report["timing"]["progress_spread_p95"],
    }


def describe(r: dict) -> str:
    """One task's row."""
    if not r.get("flown"):
        return f"no flight: {r['reason'][:160]}"
    verdict = "safe" if r["safe"] else "UNSAFE " + " ".join(r["reasons"])[:160]
    return (
        f"tolerance {r['tolerance'][0]:.3f} s / {r['tolerance'][1]:.3f}; least clearance "
        f"{r['clearance']:.3f} m, inter-drone p95 {r['inter_drone_p95']:.3f} m, progress "
        f"spread p95 {r['spread_p95']:.2f} s; {verdict}"
    )


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenes", nargs="+", default=["puzzle", "rescue"])
    parser.add_argument("--seeds", type=seeds, default=seeds("0-14"))
    parser.add_argument("--variant", nargs=2, action="append", required=True,
                        metavar=("NAME", "PLANNER_JSON"))  # fmt: skip
    parser.add_argument("--position-error", default="sitl")
    parser.add_argument("--out", type=Path, default=Path("sitl-seeds"))
    parser.add_argument(
        "--resume", action="store_true", help="read what an interrupted run left in --out"
    )
    args = parser.parse_args()
    results: dict[tuple[str, str], list[dict]] = {}
    for scene in args.scenes:
        for name, fields in args.variant:
            for seed in args.seeds:
                r = run(scene, json.loads(fields), seed, args.position_error,
                        args.out / f"{scene}-{name}-{seed}", args.resume)  # fmt: skip
                results.setdefault((scene, name), []).append(r)
                print(f"{scene} {name} {seed}: {describe(r)}", flush=True)
    print("\nscene    variant        missions  unsafe  clearance median [worst]  inter-drone p95 "
          "median [worst]")  # fmt: skip
    for (scene, name), rows in results.items():
        flown = [r for r in rows if r.get("flown")]
        unsafe = sum(not r["safe"] for r in flown)
        if not flown:
            print(f"{scene:<8} {name:<14} {0:>3}/{len(rows):<3}")
            continue
        clearance = [r["clearance"] for r in flown]
        inter = [r["inter_drone_p95"] for r in flown]
        print(f"{scene:<8} {name:<14} {sum(r['mission'] for r in rows):>3}/{len(rows):<3}    "
              f"{unsafe:>2}/{len(flown):<3} {statistics.median(clearance):.3f} "
              f"[{min(clearance):.3f}]            {statistics.median(inter):.3f} "
              f"[{max(inter):.3f}]")  # fmt: skip
    return 0


if __name__ == "__main__":
    sys.exit(main())
