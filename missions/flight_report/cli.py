"""``flycrane flight-report``: the report of a recorded flight (a SITL flight's directory,
or a task's directory and three tlogs of a real flight)."""

from __future__ import annotations

import argparse
from pathlib import Path

from missions.flight_report import report_sitl_flight, report_tlogs, write_report


def _cmd_flight_report(args: argparse.Namespace) -> int:
    if args.tlogs:
        report, plan = report_tlogs(Path(args.flight), [Path(t) for t in args.tlogs])
    else:
        report, plan = report_sitl_flight(Path(args.flight))
    out = Path(args.out or args.flight)
    files = write_report(report, plan, out, title=args.flight)
    print(report.verdict)
    for name, path in files.items():
        print(f"  {name}: {path}")
    return 0 if report.verdict.safe else 1


def register(commands: argparse._SubParsersAction) -> None:
    """Add ``flight-report`` to the ``flycrane`` command line."""
    command = commands.add_parser("flight-report", help="report a recorded flight")
    command.add_argument(
        "flight", help="a SITL flight's directory (flight.json), or a task's with --tlogs"
    )
    command.add_argument(
        "--tlogs", nargs=3, metavar="TLOG", help="drone 1, 2 and 3's tlogs of a real flight"
    )
    command.add_argument("--out", help="where to write the report (default: the directory)")
    command.set_defaults(handler=_cmd_flight_report)
