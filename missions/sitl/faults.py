"""Faults injected into a SITL flight: what a real team meets, made to happen on cue.

Each :class:`FaultPlan` names a drone and the plan time it strikes at (after the release);
the harness (:mod:`missions.sitl.harness`) makes it happen:

- ``gps``: its GNSS is switched off (SIM_GPS_DISABLE 1): the fix drops at once, its EKF
  dead-reckons and, seconds later, its failsafe lands it;
- ``link``: the ground loses it: nothing more is sent to it (heartbeats included) and the
  executor hears nothing more from it (the logs still record it, for the report);
- ``mode``: another ground station or a pilot switches it to BRAKE;
- ``motor``: one motor gives ``value`` of its thrust (SIM_ENGINE_FAIL, SIM_ENGINE_MUL;
  below about 0.7 SITL's quad cannot stay up, so tests use 0.8);
- ``late``: it starts ``value`` seconds late (stream and onboard executions hold it at its
  start), as a drone whose hand-over failed would.

SIM_ parameters are the simulator's own: on a real vehicle these faults just happen.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

FaultName = Literal["gps", "link", "mode", "motor", "late"]
KINDS: tuple[FaultName, ...] = ("gps", "link", "mode", "motor", "late")


@dataclass(frozen=True)
class FaultPlan:
    """``kind`` strikes drone ``drone`` (1-based) at plan time ``at`` [s]; ``value``: the
    motor's thrust fraction, or the late start [s]."""

    kind: FaultName
    drone: int
    at: float
    value: float = 0.0

    def __post_init__(self) -> None:
        if self.kind not in KINDS:
            raise ValueError(f"fault kind {self.kind!r}: one of {', '.join(KINDS)}")
        if self.drone not in (1, 2, 3):
            raise ValueError(f"fault drone {self.drone}: 1, 2 or 3")

    @classmethod
    def parse(cls, text: str) -> FaultPlan:
        """``KIND:DRONE:AT[:VALUE]``, e.g. ``gps:2:8`` or ``motor:1:5:0.7``."""
        parts = text.split(":")
        if len(parts) not in (3, 4):
            raise ValueError(f"{text!r}: expected KIND:DRONE:AT[:VALUE]")
        value = float(parts[3]) if len(parts) == 4 else 0.0
        return cls(parts[0], int(parts[1]), float(parts[2]), value)  # type: ignore[arg-type]
