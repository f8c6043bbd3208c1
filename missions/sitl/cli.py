"""``flycrane fly-sitl TASK_DIR``: fly a task on three ArduCopter SITL instances and report
the flight.

``--mode`` says who flies the plan (:mod:`missions.execution`): ``missions`` (the
autopilots' own waypoint missions), ``stream`` (the ground, from one clock) or ``onboard``
(a Lua player on each drone). ``--fault KIND:DRONE:AT[:VALUE[:MOTOR]]`` injects a fault
(:mod:`missions.sitl.faults`); ``--stock-sensors`` flies SITL's sensors as they come (no
barometer calibration, gyro drift on).

SITL listens on every interface, so unless this process already is in a private network
namespace, the command runs itself again inside a new one (:mod:`missions.sitl.netns`);
``--shared-network`` skips that where namespaces are unavailable (the simulators then listen
on this machine's interfaces: use it only on an isolated machine).

Exit status: 0 the flight was safe, 1 unsafe, 3 the release was refused (the vehicles did
not position themselves as the plan assumes), 2 the flight could not be flown.
"""

from __future__ import annotations

import argparse
import json
import math
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path

from pydantic import ValidationError

from flycrane.errors import FlyCraneError, field_messages
from flycrane.user_files import output_directory
from missions.execution.options import MAX_LEAD_S, MAX_START_DELAY_S, RATE_RANGE_HZ
from missions.sitl.faults import KINDS, FaultPlan
from missions.sitl.netns import bring_up_loopback, isolated, isolated_command
from missions.sitl.settings import SitlSettings

#: Exit status of a flight whose release was refused.
REFUSED = 3


def _cmd_fly_sitl(args: argparse.Namespace) -> int:
    if not args.shared_network and not isolated():
        command = [sys.executable, "-m", "flycrane.cli", *sys.argv[1:]]
        return subprocess.run(isolated_command(command), check=False).returncode
    if isolated():
        bring_up_loopback()
    # the flight's stack (MAVLink, the autopilot model's kernels, the report) loads here, in
    # the process that flies, not in the one that only starts it in its namespace
    from missions.flight_report import report_sitl_flight, write_report
    from missions.sitl.harness import SitlFlightOptions, fly_on_sitl

    chosen = {"speedup": args.speedup, "boot_speedup": args.boot_speedup}
    given = {name: value for name, value in chosen.items() if value is not None}
    if args.stock_sensors:
        given |= {"calibrated_barometers": False, "gyro_drift": True}
    try:
        settings = SitlSettings(**given)
    except ValidationError as error:
        for field, message in field_messages(error.errors()):
            print(f"fly-sitl: {field}: {message}", file=sys.stderr)
        return 2
    overrides = dict(args.parameter)
    delays = args.release_delays
    options = SitlFlightOptions(
        mode=args.mode,
        rate_hz=args.rate_hz,
        release_delays=(delays[0], delays[1], delays[2]),
        parameter_overrides=(overrides, overrides, overrides),
        faults=tuple(args.fault),
        on_fault=args.on_fault,
        lead=None if args.lead is None else (args.lead[0], args.lead[1]),
    )
    out = Path(args.out)
    try:
        if out.exists():  # the flight makes it fresh once its checks have passed
            output_directory(out)
        flight = fly_on_sitl(Path(args.task_dir), out, settings, options)
    except FlyCraneError as error:
        print(f"fly-sitl: {error}", file=sys.stderr)
        return 2
    flight.write(out)
    if flight.refused:
        print("release refused: " + "; ".join(flight.refused))
        return REFUSED
    report, plan = report_sitl_flight(out)
    files = write_report(report, plan, out, title=f"SITL flight of {args.task_dir} ({args.mode})")
    timing, true = report.timing, report.true or report.estimated
    print(
        f"{args.mode}: flown {timing.flown_duration:.2f} s of {report.planned_duration:.2f} s "
        f"planned; release spread {report.release_spread * 1000:.1f} ms, start spread "
        f"{timing.start_spread * 1000:.0f} ms; pair distance error p95 "
        f"{true.pair_error_common_p95:.3f} m at one clock ({true.source}); least clearance "
        f"{true.least_clearance:.3f} m ({true.least_clearance_bodies})"
    )
    if report.stop is not None:
        stop = report.stop
        print(
            f"team stop at {stop.commanded_at:.2f} s"
            + (f", {stop.detected_after:.2f} s after the fault" if stop.detected_after else "")
            + "; at rest after "
            + ", ".join(f"{s:.2f}" for s in stop.at_rest_after)
            + " s"
        )
    print(report.verdict)
    print(json.dumps({name: str(path) for name, path in files.items()}))
    return 0 if report.verdict.safe else 1


def _parameter(text: str) -> tuple[str, float]:
    name, _, value = text.partition("=")
    try:
        number = float(value)
    except ValueError:
        number = math.nan
    if not name or not math.isfinite(number):
        raise argparse.ArgumentTypeError(f"expected NAME=VALUE, a finite number, got {text!r}")
    return name, number


def _within(low: float, high: float, unit: str) -> Callable[[str], float]:
    """An argparse type: a number in [low, high] (NaN is in no range)."""

    def parse(text: str) -> float:
        try:
            value = float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected {unit}, got {text!r}") from None
        if not low <= value <= high:
            raise argparse.ArgumentTypeError(f"{text} is outside {low:g}-{high:g} {unit}")
        return value

    return parse


def _fault(text: str) -> FaultPlan:
    try:
        return FaultPlan.parse(text)
    except ValueError as error:
        raise argparse.ArgumentTypeError(str(error)) from None


def register(commands: argparse._SubParsersAction) -> None:
    """Add ``fly-sitl`` to the ``flycrane`` command line (entry point ``flycrane.commands``)."""
    command = commands.add_parser(
        "fly-sitl",
        help="fly a task on three ArduCopter SITL instances and report",
        description=__doc__.split("\n\n")[1],
    )
    command.add_argument("task_dir", help="a task's directory (flycrane plan --out)")
    command.add_argument("--out", default="flight", help="directory for logs and the report")
    command.add_argument(
        "--mode", choices=("missions", "stream", "onboard"), default="missions",
        help="who flies the plan: the autopilots' missions, the ground's targets from one "
        "clock, or a player on board (default: missions)",
    )  # fmt: skip
    command.add_argument(
        "--rate-hz", type=_within(*RATE_RANGE_HZ, "Hz"), default=20.0,
        help="targets per second in stream mode, ticks of the clock otherwise (10-50)",
    )  # fmt: skip
    command.add_argument(
        "--lead", nargs=2, type=_within(0.0, MAX_LEAD_S, "s"), metavar=("HORIZONTAL", "VERTICAL"),
        help="targets this far ahead of each drone's present [s], what its position "
        "controller lags them by (stream, onboard; default: the mode's, measured on "
        "ArduCopter 4.5.7's default tuning)",
    )  # fmt: skip
    command.add_argument("--speedup", type=float, help="simulation speed-up (default: 2)")
    command.add_argument(
        "--boot-speedup", type=float,
        help="simulation speed-up from the boot to the steady hold before the release "
        "(default: 10)",
    )  # fmt: skip
    command.add_argument(
        "--stock-sensors", action="store_true",
        help="SITL's sensors as they come: no barometer calibration, gyro drift on",
    )  # fmt: skip
    command.add_argument(
        "--fault", type=_fault, action="append", default=[],
        metavar="KIND:DRONE:AT[:VALUE[:MOTOR]]",
        help=f"inject a fault ({', '.join(KINDS)}) on drone 1-3 at plan time AT [s]; VALUE: "
        "a motor's thrust fraction, or a late start [s]; MOTOR: which motor weakens, 1-4 as "
        "ArduCopter numbers them (default 1: SITL's + frame's right arm)",
    )  # fmt: skip
    command.add_argument(
        "--on-fault", choices=("hold", "retreat"), default="hold",
        help="after a team stop: hold, or take back the drones whose mode was switched and "
        "retreat along the plan to its start (stream, onboard)",
    )  # fmt: skip
    command.add_argument(
        "--release-delays", nargs=3, type=_within(0.0, MAX_START_DELAY_S, "s"),
        default=(0.0, 0.0, 0.0), metavar="S",
        help="release drone 1, 2, 3 this much later [s] (missions mode; a deliberately "
        "perturbed flight)",
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
