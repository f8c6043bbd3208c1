"""``flycrane view``: a planned task's viewer page as one HTML file that opens from disk,
with a flight's flown tracks where one is given (docs/viewer.md)."""

from __future__ import annotations

import argparse
from pathlib import Path

from flycrane.errors import FieldProblem, InputError


def _same_plan(flown: Path, given: Path) -> bool:
    """Whether a flight of the task in ``flown`` is one of the task in ``given``: the same
    directory, or a copy of it (the same planned tracks)."""
    from missions.task.directory import TRACKS_FILE

    if flown.resolve() == given.resolve():
        return True
    try:
        return (flown / TRACKS_FILE).read_bytes() == (given / TRACKS_FILE).read_bytes()
    except OSError:
        return False


def _cmd_view(args: argparse.Namespace) -> int:
    from missions.flight_report.record import FLIGHT_FILE, FlightRecord
    from missions.task.directory import TaskDirectory
    from missions.viewer import FLOWN_FILE, PAGE_FILE, standalone_page, view_document

    task_dir = Path(args.task_dir)
    flight = None if args.flight is None else Path(args.flight)
    if flight is not None:
        if not (flight / FLOWN_FILE).is_file():
            raise InputError([FieldProblem("--flight", (
                f"{flight} has no {FLOWN_FILE}: give a directory `flycrane fly-sitl` or "
                "`flycrane flight-report` wrote its report into"))])  # fmt: skip
        if (flight / FLIGHT_FILE).is_file():
            flown_task = Path(FlightRecord.read(flight).task_dir)
            if not _same_plan(flown_task, task_dir):
                raise InputError([FieldProblem("--flight", (
                    f"{flight} is a flight of {flown_task}, not of {task_dir}"))])  # fmt: skip
    if args.out is not None and not args.out.strip():
        raise InputError([FieldProblem("--out", "must name a file")])
    out = task_dir / PAGE_FILE if args.out is None else Path(args.out)
    task = TaskDirectory(task_dir).task()
    document = view_document(task, task_dir, base_dir=task_dir, flown_dir=flight)
    out.write_text(standalone_page(document), encoding="utf-8")
    for note in document["notes"]:
        print(f"note: {note}")
    print(out)
    return 0


def register(commands: argparse._SubParsersAction) -> None:
    """Add ``view`` to the ``flycrane`` command line."""
    command = commands.add_parser(
        "view", help="write a planned task's viewer page (one HTML file, opens from disk)"
    )
    command.add_argument("task_dir", help="a task's directory, as `flycrane plan --out` wrote it")
    command.add_argument(
        "--flight",
        help="a flight's directory with the report's flown.json (`flycrane fly-sitl --out`, "
        "`flycrane flight-report --out`), drawn beside the plan",
    )
    command.add_argument("--out", help="the page's file (default: TASK_DIR/view.html)")
    command.set_defaults(handler=_cmd_view)
