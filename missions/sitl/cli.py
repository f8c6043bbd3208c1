"""``flycrane fly-sitl TASK_DIR``: fly a task's missions on three ArduCopter SITL instances
and report the flight.

SITL listens on every interface, so unless this process already is in a private network
namespace, the command runs itself again inside a new one (:mod:`missions.sitl.netns`);
``--shared-network`` skips that where namespaces are unavailable (the simulators then listen
on this machine's interfaces: use it only on an isolated machine).
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
from pathlib import Path

from missions.flight_report import report_sitl_flight, write_report
from missions.sitl.harness import SitlFlightOptions, fly_on_sitl
from missions.sitl.netns import bring_up_loopback, isolated, isolated_command
from missions.sitl.settings import SitlSettings


def _cmd_fly_sitl(args: argparse.Namespace) -> int:
    if not args.shared_network and not isolated():
        command = [sys.executable, "-m", "flycrane.cli", *sys.argv[1:]]
        return subprocess.run(isolated_command(command), check=False).returncode
    if isolated():
        bring_up_loopback()
    settings = SitlSettings(speedup=args.speedup) if args.speedup else SitlSettings()
    overrides = dict(args.parameter)
    delays = args.release_delays
    options = SitlFlightOptions(
        release_delays=(delays[0], delays[1], delays[2]),
        parameter_overrides=(overrides, overrides, overrides),
    )
    out = Path(args.out)
    flight = fly_on_sitl(Path(args.task_dir), out, settings, options)
    flight.write(out)
    report, plan = report_sitl_flight(out)
    files = write_report(report, plan, out, title=f"SITL flight of {args.task_dir}")
    timing, true = report.timing, report.true or report.estimated
    print(
        f"flown {timing.flown_duration:.2f} s of {report.planned_duration:.2f} s planned; "
        f"release spread {report.release_spread * 1000:.1f} ms; inter-drone error p95 "
        f"{true.inter_drone_error_p95:.3f} m ({true.source}); least clearance "
        f"{true.least_clearance:.3f} m ({true.least_clearance_bodies})"
    )
    print(report.verdict)
    print(json.dumps({name: str(path) for name, path in files.items()}))
    return 0 if report.verdict.safe else 1


def _parameter(text: str) -> tuple[str, float]:
    name, _, value = text.partition("=")
    try:
        return name, float(value)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected NAME=VALUE, got {text!r}") from None


def register(commands: argparse._SubParsersAction) -> None:
    """Add ``fly-sitl`` to the ``flycrane`` command line (entry point ``flycrane.commands``)."""
    command = commands.add_parser(
        "fly-sitl", help="fly a task's missions on three ArduCopter SITL instances and report"
    )
    command.add_argument("task_dir", help="a task's directory (flycrane plan --out)")
    command.add_argument("--out", default="flight", help="directory for logs and the report")
    command.add_argument("--speedup", type=float, help="simulation speed-up (default: 10)")
    command.add_argument(
        "--release-delays", nargs=3, type=float, default=(0.0, 0.0, 0.0), metavar="S",
        help="release drone 1, 2, 3 this much later [s] (a deliberately perturbed flight)",
    )  # fmt: skip
    command.add_argument(
        "--parameter", type=_parameter, action="append", default=[], metavar="NAME=VALUE",
        help="set on every vehicle after the plan's parameters (a deliberately wrong setting)",
    )  # fmt: skip
    command.add_argument(
        "--shared-network", action="store_true",
        help="do not isolate SITL in a private network namespace",
    )  # fmt: skip
    command.set_defaults(handler=_cmd_fly_sitl)
