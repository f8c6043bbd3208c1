"""Mission options: where, how fast, how to start and end (design.md section 8)."""

from __future__ import annotations

from datetime import UTC, datetime
from typing import Literal

import numpy as np
from numpy.typing import NDArray
from pydantic import BaseModel, ConfigDict, Field, field_validator

from missions.position_error import PositionErrorModel

#: The log's time base range: instants the MCAP log's uint64 nanoseconds and every
#: calendar library represent (years 1 and 9999 overflow a timestamp on the way).
EARLIEST_START = datetime(2000, 1, 1, tzinfo=UTC)
LATEST_START = datetime(2100, 1, 1, tzinfo=UTC)


class GeodeticOrigin(BaseModel):
    """The task frame's origin: ENU (x east, y north, z up) starts here."""

    model_config = ConfigDict(frozen=True, extra="forbid", allow_inf_nan=False)

    latitude: float = Field(47.3977, ge=-90, le=90, strict=True, description="[deg] WGS84")
    longitude: float = Field(8.5456, ge=-180, le=180, strict=True, description="[deg] WGS84")
    altitude: float = Field(488.0, ge=-500, le=9000, strict=True, description="[m] AMSL of z = 0")


#: The longest mission [s]: ten minutes, about what a multirotor carrying its share of a
#: load flies on one battery. It bounds the mission work of a task in memory (the mission
#: model samples every 10 ms, the checks every ``check_resolution``, the files store what
#: those samples show; BENCHMARKS.md "Bounded work"); ``planner.time_budget`` bounds it in
#: time. A task that cannot fit is refused before it is planned (its drones' straight-line
#: travel) and failed before its missions are built (its path).
MAX_MISSION_DURATION_S = 600.0


class MissionOptions(BaseModel):
    """How a planned path becomes three drone missions.

    Defaults: the quasi-static limits of design.md section 8 (drone speed 0.5 m/s, platform
    angular rate 0.2 rad/s) and an acceleration limit of 0.25 m/s^2, half of what a copter's
    position controller allows by default, so that speed changes at waypoints stay gentle
    for a hanging load.

    Lower bounds keep the work finite: every check samples the mission every
    ``check_resolution`` seconds, and a mission's duration grows as the speeds shrink.
    """

    model_config = ConfigDict(frozen=True, extra="forbid", allow_inf_nan=False)

    origin: GeodeticOrigin = Field(default_factory=GeodeticOrigin)
    max_drone_speed: float = Field(0.5, ge=0.05, le=5.0, strict=True, description="[m/s]")
    max_angular_rate: float = Field(
        0.2, ge=0.005, le=2.0, strict=True, description="platform [rad/s]"
    )
    max_acceleration: float = Field(
        0.25, ge=0.01, le=5.0, strict=True, description="drones [m/s^2]"
    )
    check_resolution: float = Field(
        0.1, ge=0.01, le=5.0, strict=True, description="time step [s] at which legs are checked"
    )
    max_platform_deviation: float = Field(
        0.05,
        gt=0,
        le=10.0,
        strict=True,
        description="[m] reconstructed vs planned platform point P along legs",
    )
    max_cable_length_error: float = Field(
        0.05,
        gt=0,
        le=10.0,
        strict=True,
        description="[m] how far straight legs leave the planned cable geometry",
    )
    max_leg_duration: float = Field(
        30.0,
        gt=0,
        le=3600.0,
        strict=True,
        description="[s] longest leg; long legs are fine, but keep progress visible",
    )
    autopilot_acceleration: float = Field(
        1.0,
        ge=0.05,
        le=2.5,
        strict=True,
        description="[m/s^2] how fast the autopilots change speed between legs (half their "
        "WPNAV_ACCEL); the statics' force perturbation must cover it on the platform",
    )
    start_time_utc: datetime | None = Field(
        None,
        description="planned release time: the time base of the MCAP log (default: now), "
        f"between {EARLIEST_START:%Y-%m-%d} and {LATEST_START:%Y-%m-%d}",
    )
    position_error: Literal["rtk", "sitl", "gnss", "exact"] | PositionErrorModel = Field(
        "rtk",
        description="how far each drone may be from where it is told: a preset or bounds; "
        "the obstacle clearance follows from it (missions.position_error)",
    )
    robust_clearance: bool = Field(
        True,
        strict=True,
        description="plan again with a larger obstacle clearance while the path's robust "
        "margin (its least gap less what the position error's drone errors can close there, "
        "flycrane.planning.robust_clearance) is below zero, and with another seed while its "
        "robust statics margin (its least tension or thrust margin less what the drones' own "
        "errors can take of it, flycrane.model.robust_statics) is; on by default, false "
        "keeps the one clearance of the position-error model along the whole path",
    )
    vertical_leg_speed: float = Field(
        0.1, ge=0.01, le=0.5, strict=True, description="[m/s] of lift-off and set-down legs"
    )
    set_down_approach: float = Field(
        0.1,
        ge=0.0,
        le=1.0,
        strict=True,
        description="[m] a set-down's slow vertical leg starts this much above the lowest "
        "pose that keeps the clearance, so that the path's last leg brakes there and not at "
        "the clearance's edge (missions.trajectory.vertical_legs)",
    )
    end: Literal["hold", "land"] = Field("hold", description="after the last waypoint")
    altitude_frame: Literal["relative", "amsl"] = "relative"
    home_height: float = Field(
        0.1,
        ge=0.0,
        le=2.0,
        strict=True,
        description="[m] height above the ground of each drone's position reference (its "
        "autopilot's) while it stands at its start: ArduPilot sets home there at arming, and "
        "relative altitudes count from it. ArduCopter SITL's quad stands 0.10 m high; "
        "measure yours as the altitude a drone on the ground reads above it",
    )

    def item_altitude(
        self, z: NDArray[np.float64], amsl: NDArray[np.float64]
    ) -> NDArray[np.float64]:
        """A position item's altitude [m] for ENU height ``z`` (AMSL ``amsl``): above home,
        which stands :attr:`home_height` above the ground, or AMSL."""
        return z - self.home_height if self.altitude_frame == "relative" else amsl

    def item_amsl(self, altitude: NDArray[np.float64]) -> NDArray[np.float64]:
        """The AMSL altitude [m] of an item's ``altitude`` (:meth:`item_altitude`'s
        inverse)."""
        if self.altitude_frame == "relative":
            return altitude + self.origin.altitude + self.home_height
        return altitude

    @field_validator("start_time_utc")
    @classmethod
    def _in_utc(cls, value: datetime | None) -> datetime | None:
        """An instant in UTC. The log takes its epoch time from this value: a time given
        with an offset ("16:30+02:00") must become 14:30, and a naive one is UTC (as the name
        says), not the machine's local time."""
        if value is None:
            return None
        value = value.replace(tzinfo=UTC) if value.tzinfo is None else value.astimezone(UTC)
        if not EARLIEST_START <= value < LATEST_START:
            raise ValueError(
                f"must be between {EARLIEST_START:%Y-%m-%d} and {LATEST_START:%Y-%m-%d} "
                "(UTC): the log stamps messages in nanoseconds since 1970"
            )
        return value
