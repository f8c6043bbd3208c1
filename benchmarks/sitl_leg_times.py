"""The test data of recorded SITL flights: every timed leg's duration per drone.

    python benchmarks/sitl_leg_times.py FLIGHT_DIR [FLIGHT_DIR ...] > sitl_leg_times.json

FLIGHT_DIR: ``flycrane fly-sitl`` output (``flight.json``, the tlogs, and
``sitl/sitl{i}/logs`` of each simulator). ``tests/missions/data/README.md`` describes the
file; :mod:`missions.flight_report.leg_times` measures the legs.
"""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Sequence
from pathlib import Path

from bench_input import exit_if_unreadable

from missions.flight_report.leg_times import MISSION_FIELDS, flight_record


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("flights", nargs="+", type=Path, help="flight directories")
    args = parser.parse_args(argv)
    flights = []
    for path in args.flights:
        with exit_if_unreadable(parser, path):
            flights.append(flight_record(path))
    document = {
        "about": "per-leg durations of ArduCopter 4.5.7 SITL flights; see README.md",
        "mission_fields": list(MISSION_FIELDS),
        "flights": flights,
    }
    sys.stdout.write(json.dumps(document, separators=(",", ":")) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
