"""Fly the same missions in every execution mode on three ArduCopter SITL autopilots, and
faulted flights, and print how in step and how safe each was.

    .venv/bin/python benchmarks/execution_modes.py --scenes rescue puzzle --seeds 0-9 \\
        --modes missions stream onboard --out execution-modes
    .venv/bin/python benchmarks/execution_modes.py --scenes rescue --seeds 0-11 \\
        --faults 1 --modes stream --out execution-faults

Each (scene, seed) is planned once by ``flycrane plan`` (the default planner, or the options
``--planner`` and ``--mission`` give; the ``sitl`` position-error model), then flown by
``flycrane fly-sitl --mode MODE`` (its own private network namespace, simulators stopped by
PID; ``--lead`` passed on). With ``--faults K``, each flight gets one fault drawn from a
generator seeded by the task's seed: a kind among ``gps``, ``link``, ``mode`` and ``motor``
(0.8 of one motor's thrust), a drone, a plan time between 20 % and 70 % of the plan and,
drawn last, which of the quad's four motors weakens (``--motor`` fixes it; ``--motor 1``
repeats the runs made before the motor was drawn); ``--fault-kinds`` keeps the drones and
times and draws the kind among fewer. The conditions a user would fly in:
``--stock-sensors`` and ``--parameter`` (SITL's wind, the vehicles' gains) pass to fly-sitl.
Figures are the flight report's (true positions from SIM_STATE, estimates from the
autopilots, one common clock); BENCHMARKS.md ("Execution in step") records the runs. Results
are kept in ``--out``: a rerun flies only what is missing. """

from __future__ import annotations

import argparse
import json
import random
import statistics
from pathlib import Path

from sitl_seeds import flycrane, seeds  # the seeds' syntax and the CLI runner, shared

FAULT_KINDS = ("gps", "link", "mode", "motor")


def plan(scene: str, seed: int, out: Path, planner: dict, mission: dict) -> dict:
    """The task's summary, planned once into ``out`` (``planner``: options beside the
    seed and the budget; ``mission``: beside the ``sitl`` model)."""
    summary_file = out / "summary.json"
    if not summary_file.exists():
        out.mkdir(parents=True, exist_ok=True)
        task = {"scene": scene, "planner": {**planner, "seed": seed, "time_budget": 120},
                "mission": {**mission, "position_error": "sitl"}}  # fmt: skip
        (out / "task.in.json").write_text(json.dumps(task))
        flycrane("plan", str(out / "task.in.json"), "--out", str(out))
    return json.loads(summary_file.read_text())


def fault_of(
    seed: int, duration: float, kinds: tuple[str, ...] = FAULT_KINDS, motor: int | None = None
) -> str:
    """One fault for a flight, drawn from ``seed`` (module docstring). With fewer
    ``kinds``, the drone and the time are the same as with all four: a drawn kind not
    among them is replaced by one that is; ``motor`` fixes the weak motor, else drawn."""
    draw = random.Random(seed)
    kind, drone = draw.choice(FAULT_KINDS), draw.randint(1, 3)
    kind = kind if kind in kinds else kinds[FAULT_KINDS.index(kind) % len(kinds)]
    at = round(draw.uniform(0.2, 0.7) * duration, 1)
    weak = motor or draw.randint(1, 4)
    return f"{kind}:{drone}:{at}" + (f":0.8:{weak}" if kind == "motor" else "")


def fly(
    task_dir: Path,
    out: Path,
    mode: str,
    speedup: float,
    fault: str | None,
    lead: tuple[float, float] | None = None,
    conditions: tuple[str, ...] = (),
) -> dict:
    """One flight's figures (kept in ``out/result.json``); ``conditions``: more options
    of ``fly-sitl`` (``--stock-sensors``, ``--parameter SIM_WIND_SPD=3``)."""
    result_file = out / "result.json"
    if result_file.exists():
        return json.loads(result_file.read_text())
    extra = ["--fault", fault] if fault else []
    extra += ["--lead", *map(str, lead)] if lead else []
    extra += conditions
    done = flycrane("fly-sitl", str(task_dir), "--out", str(out), "--mode", mode,
                    "--speedup", str(speedup), *extra)  # fmt: skip
    result: dict = {"mode": mode, "fault": fault, "status": done.returncode}
    report_file = out / "report.json"
    if done.returncode == 3:
        result["refused"] = done.stdout.strip()[-300:]
    elif not report_file.exists():
        result["error"] = done.stderr.strip()[-300:]
    else:
        report = json.loads(report_file.read_text())
        true, estimated = report["true"], report["estimated"]
        result |= {
            "safe": report["verdict"]["safe"],
            "reasons": report["verdict"]["reasons"],
            "pair_true_p95": true["pair_error_common_p95"],
            "pair_true_max": true["pair_error_common_max"],
            "pair_estimated_p95": estimated["pair_error_common_p95"],
            "tracking_estimated_p95": max(estimated["error_in_time_p95"]),
            "clearance_true": true["least_clearance"],
            "clearance_bodies": true["least_clearance_bodies"],
            "duration_ratio": report["timing"]["flown_duration"] / report["planned_duration"],
            "start_spread": report["timing"]["start_spread"],
            "progress_spread_max": report["timing"]["progress_spread_max"],
            "stop": report["stop"],
        }
        if (record := out / "execution.json").exists():
            result["silence_max"] = max(json.loads(record.read_text()).get("silences", [0.0]))
    out.mkdir(parents=True, exist_ok=True)
    result_file.write_text(json.dumps(result))
    return result


def spread(values: list[float], unit: float = 1.0, digits: int = 1) -> str:
    """``median (worst)`` of ``values`` in ``unit``."""
    if not values:
        return "-"
    scaled = [v / unit for v in values]
    return f"{statistics.median(scaled):.{digits}f} ({max(scaled):.{digits}f})"


def table(results: list[dict]) -> None:
    """Per scene and mode: flights, unsafe, refused, and the figures' median (worst)."""
    print(
        "scene mode: flights unsafe refused errors | pair true p95 cm | pair est p95 cm | "
        "track est p95 cm | duration % | start ms | progress max s | longest silence ms | "
        "clearance cm min (med)"
    )
    groups: dict[tuple[str, str], list[dict]] = {}
    for r in results:
        groups.setdefault((r["scene"], r["mode"]), []).append(r)
    for (scene, mode), rows in sorted(groups.items()):
        flown = [r for r in rows if "safe" in r]
        clearances = [r["clearance_true"] * 100 for r in flown]
        print(
            f"{scene} {mode}: {len(rows)} {sum(not r['safe'] for r in flown)} "
            f"{sum('refused' in r for r in rows)} {sum('error' in r for r in rows)} | "
            f"{spread([r['pair_true_p95'] for r in flown], 0.01)} | "
            f"{spread([r['pair_estimated_p95'] for r in flown], 0.01)} | "
            f"{spread([r['tracking_estimated_p95'] for r in flown], 0.01)} | "
            f"{spread([abs(r['duration_ratio'] - 1) for r in flown], 0.01)} | "
            f"{spread([r['start_spread'] for r in flown], 0.001, 0)} | "
            f"{spread([r['progress_spread_max'] for r in flown], 1.0, 2)} | "
            f"{spread([r['silence_max'] for r in flown if 'silence_max' in r], 0.001, 0)} | "
            + (f"{min(clearances):.1f} ({statistics.median(clearances):.1f})" if flown else "-")
        )
    faulted = [r for r in results if r.get("fault") and "safe" in r]
    if faulted:
        print("\nfault: safe | detected after s | healthy drones at rest after s | stop")
        for r in faulted:
            stop = r["stop"]
            if stop is None:
                print(f"{r['scene']} {r['seed']} {r['mode']} {r['fault']}: "
                      f"{'safe' if r['safe'] else 'UNSAFE'} | no team stop")  # fmt: skip
                continue
            faulty = int(r["fault"].split(":")[1]) - 1
            healthy = [s for k, s in enumerate(stop["at_rest_after"]) if k != faulty]
            detected = stop["detected_after"]
            print(
                f"{r['scene']} {r['seed']} {r['mode']} {r['fault']}: "
                f"{'safe' if r['safe'] else 'UNSAFE ' + ' '.join(r['reasons'])[:120]} | "
                f"{'-' if detected is None else f'{detected:.2f}'} | {max(healthy):.2f}"
            )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--scenes", nargs="+", default=["rescue", "puzzle"])
    parser.add_argument("--seeds", type=seeds, default=seeds("0-9"))
    parser.add_argument("--modes", nargs="+", default=["missions", "stream", "onboard"])
    parser.add_argument("--faults", type=int, default=0, help="faults per flight (0 or 1)")
    parser.add_argument(
        "--fault-kinds",
        nargs="+",
        choices=FAULT_KINDS,
        default=FAULT_KINDS,
        help="the kinds drawn (the same drones and times as with all four)",
    )
    parser.add_argument("--motor", type=int, choices=(1, 2, 3, 4),
                        help="the motor a motor fault weakens (default: drawn)")  # fmt: skip
    parser.add_argument(
        "--stock-sensors",
        action="store_true",
        help="fly-sitl's --stock-sensors: SITL's sensors as they come",
    )
    parser.add_argument(
        "--parameter",
        action="append",
        default=[],
        metavar="NAME=VALUE",
        help="fly-sitl's --parameter, e.g. SIM_WIND_SPD=3 (repeatable)",
    )
    parser.add_argument("--speedup", type=float, default=5.0)
    parser.add_argument("--boot-speedup", type=float,
                        help="fly-sitl's --boot-speedup (default: the flight's)")  # fmt: skip
    parser.add_argument("--out", type=Path, default=Path("execution-modes"))
    parser.add_argument("--lead", nargs=2, type=float, metavar=("HORIZONTAL", "VERTICAL"),
                        help="fly-sitl's --lead (default: the mode's)")  # fmt: skip
    parser.add_argument("--planner", type=json.loads, default={},
                        help='planner options as JSON, e.g. \'{"improve_time": 5}\'')  # fmt: skip
    parser.add_argument("--mission", type=json.loads, default={},
                        help='mission options as JSON: \'{"robust_clearance": true}\'')  # fmt: skip
    args = parser.parse_args()
    conditions = ("--stock-sensors",) if args.stock_sensors else ()
    conditions += tuple(a for p in args.parameter for a in ("--parameter", p))
    conditions += ("--boot-speedup", str(args.boot_speedup)) if args.boot_speedup else ()
    results = []
    for scene in args.scenes:
        for seed in args.seeds:
            task_dir = args.out / f"{scene}-{seed}" / "plan"
            summary = plan(scene, seed, task_dir, args.planner, args.mission)
            if summary["status"] != "done":
                print(f"{scene} {seed}: no mission: {summary['reason'][:160]}", flush=True)
                continue
            duration = summary["mission"]["duration"]
            kinds = tuple(args.fault_kinds)
            fault = fault_of(seed, duration, kinds, args.motor) if args.faults else None
            for mode in args.modes:
                name = mode + (f"-{fault.replace(':', '_')}" if fault else "")
                name += f"-lead{args.lead[0]:g}_{args.lead[1]:g}" if args.lead else ""
                out = args.out / f"{scene}-{seed}" / name
                result = fly(task_dir, out, mode, args.speedup, fault, args.lead, conditions)
                results.append({"scene": scene, "seed": seed} | result)
                print(f"{scene} {seed} {mode} {fault or ''}: {json.dumps(result)[:300]}",
                      flush=True)  # fmt: skip
    print()
    table(results)


if __name__ == "__main__":
    main()
