"""``flycrane mock-autopilot``: run the mock ArduCopter standalone.

Registered through the ``flycrane.commands`` entry-point group. By default the mock listens
on ``udpin:127.0.0.1:14550``, so a ground station connects to it: MAVProxy with
``--master=udpout:127.0.0.1:14550``, QGroundControl with a UDP link whose server is
127.0.0.1:14550. ``--connection udpout:127.0.0.1:14550`` makes it send to a ground station
listening there instead (what SITL's ``--out`` does). Invalid values exit with status 2 and
a one-line message (the ``flycrane`` main turns the typed errors into that).
"""

from __future__ import annotations

import argparse
import signal
import sys
import threading
from typing import Any

from flycrane.errors import FieldProblem, InputError
from missions.mock.autopilot import SITL_HOME, MockAutopilot, MockConfig
from missions.mock.config import Geodetic, Imperfections
from missions.mock.faults import FaultInjection
from missions.mock.sim_clock import SimClock

#: The longest run [s of wall time], and boot without mission space, a mock is given.
MAX_RUN_S = 1.0e6
#: The fastest a mock runs [simulated s per wall s]: beyond, it runs as fast as the CPU lets.
MAX_SPEEDUP = 1000.0
#: The largest position noise [m] (a GNSS fix without corrections errs a few metres).
MAX_NOISE_M = 100.0


def register(subparsers: Any) -> None:
    """Add the ``mock-autopilot`` subcommand to the ``flycrane`` parser."""
    p = subparsers.add_parser(
        "mock-autopilot",
        help="run a mock ArduCopter (mission protocol, arming, kinematic flight)",
        description="A mock ArduCopter for ground stations and tests. It listens on "
        "udpin:HOST:PORT (connect MAVProxy with --master=udpout:127.0.0.1:PORT, or a "
        "QGroundControl UDP link to that server), or uses --connection.",
    )
    p.add_argument("--port", type=int, default=14550, help="UDP port to listen on")
    p.add_argument("--host", default="127.0.0.1", help="address to listen on")
    p.add_argument(
        "--connection",
        metavar="STRING",
        help="any connection string instead (udpout:HOST:PORT, tcpin:HOST:PORT, "
        "/dev/ttyUSB0,57600)",
    )
    p.add_argument("--system-id", type=int, default=1, help="MAVLink system id (1..255)")
    p.add_argument(
        "--speedup", type=float, default=1.0, help="simulated seconds per wall-clock second"
    )
    p.add_argument(
        "--home",
        nargs=3,
        type=float,
        metavar=("LAT", "LON", "ALT"),
        default=(SITL_HOME.lat_deg, SITL_HOME.lon_deg, SITL_HOME.alt_m),
        help="start position: degrees, degrees, metres AMSL (default: SITL's CMAC)",
    )
    p.add_argument(
        "--boot-no-space",
        type=float,
        default=0.0,
        metavar="S",
        help="answer MISSION_COUNT with NO_SPACE for the first S seconds",
    )
    p.add_argument("--start-delay", type=float, default=0.0, metavar="S")
    p.add_argument("--speed-scale", type=float, default=1.0, help="flown / commanded speed")
    p.add_argument(
        "--slowdown",
        type=float,
        default=0.0,
        help="share of speed lost through each waypoint, 0..1",
    )
    p.add_argument(
        "--noise", type=float, default=0.0, metavar="M", help="position noise, std dev [m]"
    )
    p.add_argument("--drop", type=float, default=0.0, help="share of messages dropped, 0..1")
    p.add_argument(
        "--duplicate", type=float, default=0.0, help="share of messages duplicated, 0..1"
    )
    p.add_argument("--seed", type=int, default=0, help="of noise and message faults")
    p.add_argument(
        "--duration",
        type=float,
        metavar="S",
        help="stop after S wall-clock seconds (default: until interrupted)",
    )
    p.set_defaults(handler=run)


def run(args: argparse.Namespace) -> int:
    """Start the mock and serve until SIGINT/SIGTERM or ``--duration``."""
    limits = (  # (option, value, whether 0 is allowed, most): what a run can stand
        ("--duration", args.duration, False, MAX_RUN_S),
        ("--speedup", args.speedup, False, MAX_SPEEDUP),
        ("--boot-no-space", args.boot_no_space, True, MAX_RUN_S),
        ("--noise", args.noise, True, MAX_NOISE_M),
    )
    problems = [
        FieldProblem(name, f"must be in {'[' if zero else '('}0, {most:g}], got {value}")
        for name, value, zero, most in limits
        if value is not None and not ((0 <= value if zero else 0 < value) and value <= most)
    ]
    if problems:
        raise InputError(problems)
    faults = FaultInjection(
        drop_incoming=args.drop,
        drop_outgoing=args.drop,
        duplicate_incoming=args.duplicate,
        duplicate_outgoing=args.duplicate,
        seed=args.seed,
    )
    imperfections = Imperfections(
        start_delay_s=args.start_delay,
        speed_scale=args.speed_scale,
        waypoint_slowdown=args.slowdown,
        position_noise_m=args.noise,
        seed=args.seed,
    )
    try:
        home = Geodetic(*args.home)
    except InputError as error:
        raise error.under("--home") from None
    config = MockConfig(
        system_id=args.system_id,
        home=home,
        boot_no_space_s=args.boot_no_space,
        imperfections=imperfections,
        faults=faults,
    )
    clock = SimClock(speedup=args.speedup)
    address = args.connection or f"udpin:{args.host}:{args.port}"
    stop = threading.Event()
    previous = {
        sig: signal.signal(sig, lambda *_: stop.set()) for sig in (signal.SIGINT, signal.SIGTERM)
    }
    try:
        mock = MockAutopilot(address, config, clock)
    except OSError as error:
        where = "--connection" if args.connection else "--host"
        raise InputError([FieldProblem(where, f"{address}: {error.strerror or error}")]) from None
    try:
        with mock:
            print(
                f"mock autopilot: system {config.system_id} on {address}, "
                f"speed-up {clock.speedup:g}; Ctrl-C stops it",
                file=sys.stderr,
                flush=True,
            )
            stop.wait(args.duration)
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)
    return 0
