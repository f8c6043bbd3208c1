"""How a mock vehicle is configured: where it starts, its straight legs' kinematics, and how
it departs from the ideal (:mod:`.kinematic_flight` says what each does)."""

from __future__ import annotations

import math
from dataclasses import dataclass

from flycrane.errors import FieldProblem, InputError
from flycrane.quantities import MAX_SEED
from missions.autopilots.ardupilot import MIN_GROUND_SPEED

#: How far from sea level [m] a mock's home may be, well within what MAVLink's altitudes
#: (millimetres in 32 bits) carry.
ALTITUDE_RANGE_M = 1.0e5


def _positive(owner: str, **values: float) -> None:
    problems = [
        FieldProblem(k, f"must be finite and > 0, got {v}")
        for k, v in values.items()
        if not 0 < v < math.inf
    ]
    if problems:
        raise InputError(problems, source=owner)


@dataclass(frozen=True)
class Geodetic:
    """A WGS84 position: latitude, longitude [deg], altitude AMSL [m]."""

    lat_deg: float
    lon_deg: float
    alt_m: float

    def __post_init__(self) -> None:
        problems = []
        if not -90.0 <= self.lat_deg <= 90.0:
            problems.append(FieldProblem("lat_deg", f"must be in [-90, 90], got {self.lat_deg}"))
        if not -180.0 <= self.lon_deg <= 180.0:
            problems.append(FieldProblem("lon_deg", f"must be in [-180, 180], got {self.lon_deg}"))
        if not -ALTITUDE_RANGE_M <= self.alt_m <= ALTITUDE_RANGE_M:
            bound = f"[-{ALTITUDE_RANGE_M:g}, {ALTITUDE_RANGE_M:g}]"
            problems.append(FieldProblem("alt_m", f"must be in {bound}, got {self.alt_m}"))
        if problems:
            raise InputError(problems, source="Geodetic")


@dataclass(frozen=True)
class Dynamics:
    """The mock's straight legs (NAV_WAYPOINT, takeoff, landing): speed limits before any
    DO_CHANGE_SPEED and the acceleration; spline legs take theirs from the vehicle's
    parameters instead (module docstring)."""

    cruise_speed_mps: float = 5.0
    max_accel_mps2: float = 2.5
    climb_speed_mps: float = 2.5
    descent_speed_mps: float = 1.5
    land_speed_mps: float = 0.5
    #: smaller DO_CHANGE_SPEED ground speeds are ignored (ArduCopter's floor)
    min_ground_speed_mps: float = MIN_GROUND_SPEED
    #: how high its position reference stands above the ground it rests on [m], where
    #: arming sets home: ArduCopter SITL's quad, its frame height (BENCHMARKS.md, "Home
    #: height")
    rest_height_m: float = 0.1

    def __post_init__(self) -> None:
        speeds = {k: getattr(self, k) for k in self.__dataclass_fields__ if k != "rest_height_m"}
        _positive("Dynamics", **speeds)
        if not self.rest_height_m >= 0:
            raise InputError(
                [FieldProblem("rest_height_m", f"must be >= 0, got {self.rest_height_m}")],
                source="Dynamics",
            )


@dataclass(frozen=True)
class Imperfections:
    """How one mock vehicle departs from the ideal (module docstring); defaults: none."""

    start_delay_s: float = 0.0  #: from MISSION_START to moving [s]
    speed_scale: float = 1.0  #: flown speed / commanded speed
    waypoint_slowdown: float = 0.0  #: speed lost through a waypoint, 0 (none) .. 1 (stop)
    position_noise_m: float = 0.0  #: std dev of reported position, per axis [m]
    clock_offset_s: float = 0.0  #: this vehicle's UTC error [s]
    seed: int = 0  #: of the position noise

    def __post_init__(self) -> None:
        problems = []
        if not 0 <= self.start_delay_s < math.inf:
            problems.append(
                FieldProblem("start_delay_s", f"must be finite and >= 0: {self.start_delay_s}")
            )
        if not 0 < self.speed_scale < math.inf:
            problems.append(
                FieldProblem("speed_scale", f"must be finite and > 0: {self.speed_scale}")
            )
        if not 0.0 <= self.waypoint_slowdown <= 1.0:
            problems.append(
                FieldProblem("waypoint_slowdown", f"must be in [0, 1]: {self.waypoint_slowdown}")
            )
        if not 0 <= self.position_noise_m < math.inf:
            problems.append(
                FieldProblem(
                    "position_noise_m", f"must be finite and >= 0: {self.position_noise_m}"
                )
            )
        if not math.isfinite(self.clock_offset_s):
            problems.append(
                FieldProblem("clock_offset_s", f"must be finite: {self.clock_offset_s}")
            )
        if not 0 <= self.seed <= MAX_SEED:
            problems.append(FieldProblem("seed", f"must be in 0..{MAX_SEED}: {self.seed}"))
        if problems:
            raise InputError(problems, source="Imperfections")
