"""Faults injected into a SITL flight: what a real team meets, made to happen on cue.

Each :class:`FaultPlan` names a drone and the plan time it strikes at (after the release);
the harness (:mod:`missions.sitl.harness`) makes it happen:

- ``gps``: its GNSS is switched off (SIM_GPS_DISABLE 1): the fix drops at once, its EKF
  dead-reckons and, seconds later, its failsafe lands it;
- ``link``: the ground loses it: nothing more is sent to it (heartbeats included) and the
  executor hears nothing more from it (the logs still record it, for the report);
- ``mode``: another ground station or a pilot switches it to BRAKE;
- ``motor``: motor ``motor`` gives ``value`` of its thrust (SIM_ENGINE_FAIL, SIM_ENGINE_MUL;
  below about 0.7 SITL's quad cannot stay up, so tests use 0.8). Which motor says which
  way the drone tips: SITL's quad is a + frame (FRAME_TYPE 0), whose motor 1 is on the
  right arm, 2 the left, 3 the front and 4 the back, and the drones fly facing north, so
  a weak motor 1 tips its drone east;
- ``late``: it starts ``value`` seconds late (stream and onboard executions hold it at its
  start), as a drone whose hand-over failed would.

SIM_ parameters are the simulator's own: on a real vehicle these faults just happen.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Literal

from flycrane.errors import FieldProblem, InputError

FaultName = Literal["gps", "link", "mode", "motor", "late"]
KINDS: tuple[FaultName, ...] = ("gps", "link", "mode", "motor", "late")
#: The kinds whose strength is given (VALUE), and what it is.
VALUED = ("motor", "late")
VALUED_HELP = "a motor's thrust fraction, e.g. motor:1:5:0.8; a late start's seconds, late:2:0:1"


@dataclass(frozen=True)
class FaultPlan:
    """``kind`` strikes drone ``drone`` (1-based) at plan time ``at`` [s]; ``value``: the
    motor's thrust fraction, or the late start [s]; ``motor``: which motor weakens, as
    ArduCopter numbers them (1-4)."""

    kind: FaultName
    drone: int
    at: float
    value: float = 0.0
    motor: int = 1

    def __post_init__(self) -> None:
        if self.kind not in KINDS:
            raise ValueError(f"fault kind {self.kind!r}: one of {', '.join(KINDS)}")
        if self.drone not in (1, 2, 3):
            raise ValueError(f"fault drone {self.drone}: 1, 2 or 3")
        if self.motor not in (1, 2, 3, 4):
            raise ValueError(f"fault motor {self.motor}: 1-4, as ArduCopter numbers a quad's")
        if not (math.isfinite(self.at) and self.at >= 0.0):
            raise ValueError(f"fault time {self.at}: seconds of plan time, at least 0")
        if self.kind == "late" and self.at != 0.0:
            raise ValueError(f"fault time {self.at}: a late start strikes at the start, 0")
        if self.kind == "motor" and not 0.0 <= self.value < 1.0:
            raise ValueError(
                f"motor thrust fraction {self.value}: at least 0 and below 1 (a healthy motor)"
            )
        if self.kind == "late" and not (math.isfinite(self.value) and self.value > 0.0):
            raise ValueError(f"late start {self.value}: seconds, more than 0")

    @classmethod
    def parse(cls, text: str) -> FaultPlan:
        """``KIND:DRONE:AT[:VALUE[:MOTOR]]``, e.g. ``gps:2:8``, ``motor:1:5:0.7`` (motor 1)
        or ``motor:1:5:0.8:3``."""
        parts = text.split(":")
        if parts[0] not in KINDS:
            raise ValueError(f"fault kind {parts[0]!r}: one of {', '.join(KINDS)}")
        if len(parts) not in (3, 4, 5):
            raise ValueError(f"{text!r}: expected KIND:DRONE:AT[:VALUE[:MOTOR]]")
        if len(parts) == 5 and parts[0] != "motor":
            raise ValueError(f"{text!r}: only a motor fault names a motor")
        valued = parts[0] in VALUED
        if valued != (len(parts) >= 4):
            needs = "needs" if valued else "takes no"
            raise ValueError(f"{text!r}: a {parts[0]} fault {needs} VALUE ({VALUED_HELP})")
        try:
            drone, at = int(parts[1]), float(parts[2])
            value = float(parts[3]) if valued else 0.0
            motor = int(parts[4]) if len(parts) == 5 else 1
        except ValueError:
            raise ValueError(
                f"{text!r}: DRONE and MOTOR are whole numbers, AT and VALUE numbers"
            ) from None
        return cls(parts[0], drone, at, value, motor)  # type: ignore[arg-type]


def check_within(faults: Sequence[FaultPlan], duration: float) -> None:
    """Refuse, before a flight starts, a fault that would strike at or after the plan's end
    (``duration`` [s]): it would never happen, and the flight would be reported as if it
    had been asked for without it.

    Raises
    ------
    InputError
        Naming each such fault and the plan's end.
    """
    problems = [
        FieldProblem(
            "fault",
            f"{f.kind}:{f.drone}:{f.at:g} strikes at or after the plan's "
            f"end at {duration:.2f} s: it would never happen",
        )
        for f in faults
        if f.kind != "late" and f.at >= duration
    ]
    if problems:
        raise InputError(problems)
