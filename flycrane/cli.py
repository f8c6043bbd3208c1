"""The ``flycrane`` command line.

Subcommands of this package: ``statics`` and ``system``. Other packages add theirs through
the ``flycrane.commands`` entry-point group (a callable taking the subparsers object), so
this module never imports them and dependencies keep pointing one way.
"""

from __future__ import annotations

import argparse
import gc
import json
import logging
import math
import sys
from collections.abc import Callable, Sequence
from importlib.metadata import entry_points
from pathlib import Path

import numpy as np
from pydantic import TypeAdapter, ValidationError

from flycrane.errors import FieldProblem, FlyCraneError, InputError
from flycrane.execution import MAX_WORKERS, scheduler_address
from flycrane.model.cable_system import CableSystem
from flycrane.model.cost import CostForm
from flycrane.model.kinematics import as_configurations
from flycrane.model.statics import evaluate_statics
from flycrane.model.statics_summary import statics_summary
from flycrane.model.system_spec import SystemSpec, load_system, save_system
from flycrane.quantities import MAX_LENGTH, MAX_TIME_BUDGET, Configuration
from flycrane.user_files import output_directory
from flycrane.world.scene import list_scenes, load_scene

#: The configuration the quick start evaluates: hovering 5 m up, level, alphas at 1 rad.
DEFAULT_CONFIGURATION = (0.0, 0.0, 5.0, 0.0, 0.0, 0.0, 1.0, 1.0, 1.0)
#: The names of q's components, in order (design.md s.3).
Q_NAMES = ("x", "y", "z", "phi", "theta", "sigma", "alpha1", "alpha2", "alpha3")
#: Most seeds ``bench`` runs per scene and planner: every run's record is kept in memory.
MAX_RUNS = 10_000


def _load_spec(path: str | None) -> SystemSpec:
    return load_system(path) if path else SystemSpec()


def format_statics(summary: dict) -> str:
    """A readable table of :func:`statics_summary`; "n/a" where the statics are undefined
    (a singular configuration has no tensions, and so no margins)."""
    q = summary["configuration"]
    fmt = lambda v: f"{'n/a':>9}" if v is None else f"{v:9.3f}"  # noqa: E731
    lines = [
        "configuration: " + ", ".join(f"{k}={v:g}" for k, v in q.items()),
        "",
        "cable  f0 [N]     v [N]      t_lo [N]   t_hi [N]   range [N]        "
        "slack mgn  overload mgn",
    ]
    for c in summary["cables"]:
        lines.append(
            f"{c['cable']:>5}  {fmt(c['nominal_tension'])}  {fmt(c['half_width'])}  "
            f"{fmt(c['tension_low'])}  {fmt(c['tension_high'])}  "
            f"[{c['tension_min']:g}, {c['tension_max']:g}]{'':<8}"
            f"{fmt(c['slack_margin'])}  {fmt(c['overload_margin'])}"
        )
    lines += ["", "drone  position [m]                 |T0| [N]   m_k [N]    h_k [N]    margin [N]"]
    for d in summary["drones"]:
        t0 = d["nominal_thrust"]
        norm = None if None in t0 else float(np.linalg.norm(t0))
        pos = "(" + ", ".join(f"{v:7.3f}" for v in d["position"]) + ")"
        lines.append(
            f"{d['drone']:>5}  {pos:<28} {fmt(norm)}  {fmt(d['thrust_bound'])}  "
            f"{d['max_thrust']:9.3f}  {fmt(d['thrust_margin'])}"
        )
    cost = summary["cost"]
    lines += [
        "",
        f"cost ({summary['cost_form']}): {'inf' if cost is None else f'{cost:.6g}'}",
        f"feasible: {'yes' if summary['feasible'] else 'no'}",
    ]
    lines += [f"  violated: {v['message']}" for v in summary["violations"]]
    return "\n".join(lines)


def _cmd_statics(args: argparse.Namespace) -> int:
    system = CableSystem.from_spec(_load_spec(args.system))
    try:  # the bounds every input schema keeps (flycrane.quantities), as the service's
        TypeAdapter(Configuration).validate_python(tuple(args.q))
    except ValidationError as error:
        names = [f"q.{Q_NAMES[int(e['loc'][0])]}" for e in error.errors()]
        problems = [FieldProblem(n, e["msg"]) for n, e in zip(names, error.errors(), strict=True)]
        raise InputError(problems) from None
    q = as_configurations(args.q)
    report = evaluate_statics(system, q)
    summary = statics_summary(system, report, CostForm(args.cost_form))
    print(json.dumps(summary, indent=2) if args.json else format_statics(summary))
    return 0


def _cmd_system(args: argparse.Namespace) -> int:
    spec = _load_spec(args.system)
    if args.write is not None:
        if not args.write.strip():
            raise InputError([FieldProblem("--write", "an empty file name")])
        try:
            save_system(spec, args.write)
        except OSError as error:
            reason = error.strerror or str(error)
            raise InputError([FieldProblem("--write", f"{args.write}: {reason}")]) from None
        print(f"wrote {args.write}")
    else:
        print(json.dumps(spec.model_dump(mode="json", by_alias=True, exclude_none=True), indent=2))
    return 0


def _cmd_bench(args: argparse.Namespace) -> int:
    from flycrane.analysis.benchmark import (
        RunRecord,
        format_margins,
        format_table,
        run_benchmark,
        summarize,
        write_results,
    )
    from flycrane.analysis.profiles import least_margins, path_profile, plot_profile_bands
    from flycrane.execution import executor_for, stop_executor
    from flycrane.planning.planners import PlannerOptions
    from flycrane.planning.problem import PlanningProblem

    for scene in args.scenes:
        load_scene(scene)  # unknown names and bad files fail here, before any work starts
    base = PlannerOptions(step=args.step)
    out = output_directory(args.out)
    total = len(args.scenes) * len(args.planners) * args.runs
    records = []

    def order(r: RunRecord) -> tuple[int, int, int]:
        return args.scenes.index(r.scene), args.planners.index(r.planner), r.seed

    executor = executor_for(args.cluster, args.workers)
    try:
        for record in run_benchmark(
            executor, args.scenes, args.planners, args.runs, args.budget, base
        ):
            records.append(record)
            print(
                f"[{len(records)}/{total}] {record.scene} {record.planner} seed {record.seed}: "
                f"{record.status} in {record.time:.2f} s",
                file=sys.stderr,
                flush=True,
            )
    except KeyboardInterrupt:
        # the runs not started are dropped, the running ones stopped (their workers
        # killed), and those that finished are kept
        stop_executor(executor)
        records.sort(key=order)
        write_results(records, summarize(records), out)
        print(f"interrupted: the {len(records)} of {total} runs that finished are in {out}",
              file=sys.stderr)  # fmt: skip
        return 130
    executor.shutdown()
    records.sort(key=order)
    rows = summarize(records)
    print(format_table(rows), flush=True)  # before the files: a full disk must not lose it
    write_results(records, rows, out)
    margins, figures = {}, {}
    for scene, label in zip(args.scenes, scene_labels(args.scenes), strict=True):
        problem = PlanningProblem.named(scene)
        figures[label] = {
            planner: [
                path_profile(problem.system, problem.space, np.array(r.path))
                for r in records
                if r.scene == scene and r.planner == planner and r.solved
            ]
            for planner in args.planners
        }
        for planner, profiles in figures[label].items():
            margins[label, planner] = [least_margins(p, problem.system) for p in profiles]
    print(format_margins(margins), flush=True)
    failed = 0
    for scene, label in zip(args.scenes, scene_labels(args.scenes), strict=True):
        figure = out / f"fig6_{label}.png"
        try:
            plot_profile_bands(
                figures[label],
                PlanningProblem.named(scene).system,
                figure,
                title=f"{label}: tension and thrust ranges along the paths",
            )
        except (OSError, ValueError) as error:
            failed += 1
            print(f"bench: {figure} not written: {error}", file=sys.stderr)
    print(f"results in {out}/ (runs.csv, summary.json, fig6_<scene>.png)")
    return 1 if failed else 0


def scene_labels(scenes: Sequence[str]) -> list[str]:
    """A file-name-safe label per scene: a shipped scene's name, a scene file's stem (with
    its position where two share one)."""
    stems = [Path(scene).stem for scene in scenes]
    return [stem if stems.count(stem) == 1 else f"{stem}-{k + 1}" for k, stem in enumerate(stems)]


def _positive(kind: type[int] | type[float], most: float = math.inf) -> Callable[[str], float]:
    """An argparse type: a finite number of ``kind`` above 0 and at most ``most``."""

    def parse(text: str) -> float:
        try:
            value = kind(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"not a number: {text!r}") from None
        if not 0 < value <= most:
            raise argparse.ArgumentTypeError(f"must be above 0 and at most {most:g}, got {text}")
        return value

    return parse


def _scheduler(text: str) -> str:
    """An argparse type: a Dask scheduler's address (:func:`scheduler_address`)."""
    try:
        return scheduler_address(text)
    except ValueError as error:
        raise argparse.ArgumentTypeError(str(error)) from None


def build_parser(argv: Sequence[str] = ()) -> argparse.ArgumentParser:
    """The command line; of the plug-in commands (entry points ``flycrane.commands``) only the
    one ``argv`` names is loaded, all of them when it names none (``--help``, a typo): each
    imports its own stack (MAVLink, SITL, the service), which every other command would
    pay for."""
    parser = argparse.ArgumentParser(
        prog="flycrane",
        description="FlyCrane: statics, planning and MAVLink missions for a 3-drone aerial crane",
    )
    parser.add_argument("-v", "--verbose", action="store_true", help="log progress")
    sub = parser.add_subparsers(dest="command", required=True)

    statics = sub.add_parser("statics", help="tensions, thrusts, margins and cost at q")
    statics.add_argument("--system", metavar="FILE", help="system .toml/.json (default: benchmark)")
    statics.add_argument(
        "--q",
        nargs=9,
        type=float,
        metavar="V",
        default=list(DEFAULT_CONFIGURATION),
        help="x y z [m] phi theta sigma [rad] alpha1 alpha2 alpha3 [rad] "
        "(default: 0 0 5 0 0 0 1 1 1)",
    )
    statics.add_argument("--cost-form", choices=[f.value for f in CostForm], default="normalized")
    statics.add_argument("--json", action="store_true", help="print JSON instead of a table")
    statics.set_defaults(handler=_cmd_statics)

    system = sub.add_parser("system", help="print a system description, or write it to a file")
    system.add_argument("--system", metavar="FILE", help="system to read (default: benchmark)")
    system.add_argument("--write", metavar="FILE", help="write it as .toml or .json")
    system.set_defaults(handler=_cmd_system)

    bench = sub.add_parser(
        "bench",
        help="Table I and Fig. 6: planners over scenes and seeds",
        description="Plan every scene with every planner for seeds 0..RUNS-1 (in parallel "
        "processes, or on a Dask cluster); write runs.csv, summary.json and a Fig. 6 plot "
        "per scene to --out, and print Table I and the paths' least margins.",
    )
    bench.add_argument(
        "--scenes",
        nargs="+",
        default=["rescue", "puzzle"],
        metavar="SCENE",
        help=f"shipped scenes ({', '.join(list_scenes())}) or scene files (.toml); "
        "default: rescue puzzle",
    )
    bench.add_argument(
        "--planners",
        nargs="+",
        default=["trrt", "rrt", "ompl-trrt", "ompl-rrt"],
        # planners.Algorithm's values, written out: importing the planners here would load
        # the planning stack for every command
        choices=["trrt", "rrt", "bitrrt", "ompl-trrt", "ompl-rrt", "ompl-rrtconnect"],
        metavar="PLANNER",
        help="trrt (the paper's T-RRT), rrt, bitrrt (ours), and OMPL's ompl-trrt, ompl-rrt, "
        "ompl-rrtconnect; default: trrt rrt ompl-trrt ompl-rrt (the paper's Table I)",
    )
    bench.add_argument(
        "--runs",
        type=_positive(int, MAX_RUNS),
        default=100,
        help=f"seeds per scene and planner (100; at most {MAX_RUNS})",
    )
    bench.add_argument(
        "--budget",
        type=_positive(float, MAX_TIME_BUDGET),
        default=60.0,
        help=f"planner seconds per run (60; at most {MAX_TIME_BUDGET:g})",
    )
    bench.add_argument(
        "--step",
        type=_positive(float, MAX_LENGTH),
        help=f"extension step (default: planner default; at most {MAX_LENGTH:g})",
    )
    bench.add_argument(
        "--workers", type=_positive(int, MAX_WORKERS), help="processes (default: all CPUs)"
    )
    bench.add_argument(
        "--cluster",
        type=_scheduler,
        metavar="ADDRESS",
        help="run on the Dask cluster whose scheduler is at ADDRESS (tcp://host:8786) "
        "instead of local processes",
    )
    bench.add_argument("--out", default="bench-results", help="directory for the results")
    bench.set_defaults(handler=_cmd_bench)

    plugins = entry_points(group="flycrane.commands")
    named = next((a for a in argv if not a.startswith("-")), None)
    for entry in plugins:
        if named not in plugins.names or entry.name == named:
            entry.load()(sub)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else list(argv)
    args = build_parser(argv).parse_args(argv)
    logging.basicConfig(
        level=logging.INFO if args.verbose else logging.WARNING,
        format="%(levelname)s %(name)s: %(message)s",
    )
    try:
        return int(args.handler(args))
    except FlyCraneError as error:
        print(f"flycrane {args.command}: error: {error}", file=sys.stderr)
        return 2
    except BrokenPipeError:  # the reader went away (``| head``): nothing left to say
        sys.stderr.close()
        return 1
    except OSError as error:
        print(f"flycrane {args.command}: error: {error}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"flycrane {args.command}: interrupted", file=sys.stderr)
        return 130


def run() -> None:
    """The ``flycrane`` command (console script and ``python -m flycrane.cli``): :func:`main`,
    then exit with its status. What is still alive is frozen out of the garbage collections
    the interpreter runs at exit, which would traverse numba's and matplotlib's object
    graphs only for the process to end. By then the commands have closed their files;
    atexit handlers (logging's flush) still run."""
    status = main()
    gc.freeze()
    sys.exit(status)


if __name__ == "__main__":
    run()
