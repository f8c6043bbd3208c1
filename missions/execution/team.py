"""The team failsafe: what makes all three drones stop together.

A cable-coupled team cannot let one drone react alone: a drone that stops, lands or
returns while the other two fly on drags the load (design.md section 10). So the ground
watches every drone and, on the first fault of any, stops the group clock
(:mod:`missions.execution.group_clock`) for all three at once; the operator then resumes
or sets the load down together.

:class:`TeamMonitor` is pure logic: it is fed each drone's telemetry (:meth:`observe`)
and asked for faults at a common time (:meth:`faults`). A fault is, for one drone:

- ``link``: nothing heard for ``link_timeout`` seconds (the executor discounts the ground's
  own pauses, :data:`missions.execution.executor.GROUND_PAUSE_S`);
- ``mode``: its flight mode is not the one the execution commands (a pilot's switch, a
  failsafe's LAND or RTL, a mode change from another ground station);
- ``failsafe``: it reports a failsafe or emergency state (HEARTBEAT system status);
- ``ekf``: its estimate lost a flag the plan needs (EKF_STATUS_REPORT);
- ``gps``: its fix fell below the position-error model's (GPS_RAW_INT fix type);
- ``stray``: it is farther than ``stray_distance`` from its target;
- ``attitude``: its roll and pitch are more than ``attitude_error`` from what its own
  attitude controller asks for: it lost authority (a weak motor, a broken propeller, a
  snag), which shows in its attitude a tenth of a second before it strays.

Each is reported once, with the common time it was detected and what was seen.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from enum import StrEnum

#: MAV_STATE values that mean the vehicle is in a failsafe or worse.
MAV_STATE_CRITICAL, MAV_STATE_EMERGENCY = 5, 6
#: EKF_STATUS_REPORT flags a position-holding flight needs: attitude, horizontal and
#: vertical velocity, absolute horizontal and vertical position.
EKF_NEEDED = 1 | 2 | 4 | 16 | 32


class FaultKind(StrEnum):
    LINK = "link"
    MODE = "mode"
    FAILSAFE = "failsafe"
    EKF = "ekf"
    GPS = "gps"
    STRAY = "stray"
    ATTITUDE = "attitude"


@dataclass(frozen=True)
class Fault:
    """A drone's fault: which drone (1-based), what, when (common time [s]) and what was
    seen."""

    drone: int
    kind: FaultKind
    time: float
    detail: str

    def __str__(self) -> str:
        return f"drone {self.drone}: {self.kind} at {self.time:.2f} s ({self.detail})"


@dataclass(frozen=True)
class MonitorLimits:
    """When a drone is faulty (module docstring)."""

    #: [s] of common time without a message: the aim's 0.2 s from the fault to the stop
    #: (the vehicles stream their position every 0.04 s); faster than real time the executor
    #: raises it to the host's pauses (:data:`missions.execution.executor.GROUND_PAUSE_S`)
    link_timeout: float = 0.2
    stray_distance: float = 0.25  #: [m] from its target
    min_fix_type: int = 3  #: GPS_RAW_INT fix type the position-error model needs
    attitude_error: float = 5.0  #: [deg] of roll and pitch from the controller's target


@dataclass
class _Drone:
    last_heard: float | None = None
    mode: int | None = None
    system_status: int | None = None
    ekf_flags: int | None = None
    fix_type: int | None = None
    error: float = 0.0  #: distance to its target [m]
    attitude_error: float = 0.0  #: [deg] from its attitude controller's target


@dataclass
class TeamMonitor:
    """Faults of three drones (module docstring). ``expected_mode``: the custom mode the
    execution commands (ArduCopter: 4 GUIDED, 3 AUTO)."""

    expected_mode: int
    limits: MonitorLimits = field(default_factory=MonitorLimits)
    drones: list[_Drone] = field(default_factory=lambda: [_Drone() for _ in range(3)])
    reported: list[Fault] = field(default_factory=list)

    def heard(self, drone: int, t: float) -> None:
        """Drone ``drone`` (0-based) was heard at common time ``t``."""
        self.drones[drone].last_heard = t

    def observe(
        self,
        drone: int,
        *,
        mode: int | None = None,
        system_status: int | None = None,
        ekf_flags: int | None = None,
        fix_type: int | None = None,
        error: float | None = None,
        attitude_error: float | None = None,
    ) -> None:
        """What drone ``drone`` (0-based) reported last (only the given fields change)."""
        state = self.drones[drone]
        for name, value in (
            ("mode", mode),
            ("system_status", system_status),
            ("ekf_flags", ekf_flags),
            ("fix_type", fix_type),
            ("error", error),
            ("attitude_error", attitude_error),
        ):
            if value is not None:
                setattr(state, name, value)

    def current(self, k: int, t: float) -> list[tuple[FaultKind, str]]:
        """What is wrong with drone ``k`` (0-based) at common time ``t``, reported or not."""
        return self._seen(k, t)

    def _seen(self, k: int, t: float) -> list[tuple[FaultKind, str]]:
        state, limits = self.drones[k], self.limits
        found: list[tuple[FaultKind, str]] = []
        if state.last_heard is not None and t - state.last_heard > limits.link_timeout:
            found.append((FaultKind.LINK, f"silent for {t - state.last_heard:.2f} s"))
        if state.mode is not None and state.mode != self.expected_mode:
            found.append((FaultKind.MODE, f"mode {state.mode}, not {self.expected_mode}"))
        if state.system_status in (MAV_STATE_CRITICAL, MAV_STATE_EMERGENCY):
            found.append((FaultKind.FAILSAFE, f"system status {state.system_status}"))
        if state.ekf_flags is not None and state.ekf_flags & EKF_NEEDED != EKF_NEEDED:
            found.append((FaultKind.EKF, f"EKF flags {state.ekf_flags:#x}"))
        if state.fix_type is not None and state.fix_type < limits.min_fix_type:
            found.append((FaultKind.GPS, f"fix type {state.fix_type} < {limits.min_fix_type}"))
        if state.error > limits.stray_distance:
            found.append((FaultKind.STRAY, f"{state.error:.3f} m from its target"))
        if state.attitude_error > limits.attitude_error:
            found.append((FaultKind.ATTITUDE, f"{state.attitude_error:.1f} deg from the "
                          "attitude its controller asks for"))  # fmt: skip
        return found

    def faults(self, t: float) -> list[Fault]:
        """The faults first seen at common time ``t`` (each kind once per drone)."""
        new = []
        known = {(f.drone, f.kind) for f in self.reported}
        for k in range(3):
            for kind, detail in self._seen(k, t):
                if (k + 1, kind) not in known:
                    new.append(Fault(k + 1, kind, t, detail))
        self.reported.extend(new)
        return new
