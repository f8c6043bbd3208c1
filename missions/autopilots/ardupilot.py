"""What ArduCopter (4.5) does with our missions, and the parameters the plan assumes.

The one place that states ArduCopter's behaviour; other modules refer here. Each fact was
read in ArduPilot's source or seen on the 4.5.7 SITL binary (design.md section 9;
``docs/missions.md`` "What ArduCopter does"; the flights behind them are in BENCHMARKS.md).

- **Timed legs are spline waypoints** (NAV_SPLINE_WAYPOINT). A straight NAV_WAYPOINT leg
  is an S-curve built when the *previous* waypoint starts, with the speed in force then: a
  DO_CHANGE_SPEED before a leg reaches it one leg late and only partly (short legs keep the
  old speed), so straight legs cannot be timed one by one. A spline leg reads its speed
  limits at every step, so each leg flies at its own speed (:mod:`missions.autopilots.spline`
  models it step by step: its tangents, its speed law, and the position controller it gets
  no acceleration feed-forward from).
- **Around a spline leg**: ArduCopter takes the next nav item's location when it sets a
  spline leg up (a zero latitude and longitude, or altitude, stand for the leg's own:
  ``loc_from_cmd``), so a NAV_DELAY, which has none, must not stand next to a spline
  waypoint (the legs before and after it are "reached" at once). A spline leg after any
  other nav item starts from rest.
- **Home**: arming sets home where the vehicle stands (its position reference, a frame
  height above the ground), and relative altitudes count from it. Seq 0 of a mission is
  the home slot: it reads back as the current home, whatever was uploaded there.
- **Start**: takeoff to the start, hold there in NAV_LOITER_UNLIM, released by the ground
  station with MISSION_SET_CURRENT to the item after the hold, sent to the three back to
  back. The take-offs do not lift together, a take-off closes its last centimetres of
  height slowly, and any hold timer runs from each drone's own arrival; a release sent back
  to back reaches the three together. MISSION_SET_CURRENT during a mission runs the named
  item at once, its DO items first, keeping the speed limits set so far.
- **Speeds**: DO_CHANGE_SPEED ground (param1 1; 0, airspeed, is Copter's ground speed too),
  climb (2) and descent (3) speeds; a ground speed below :data:`MIN_GROUND_SPEED`
  (WPNAV_WP_SPEED_MIN) is ignored, climb and descent speeds have no floor. **Only the first
  DO item before a leg runs before the leg is set up**: AP_Mission starts one DO item with
  the nav item and each further one a main-loop tick (2.5 ms) later, after the leg has
  fixed the speed it may end with (the next leg's entry limit, which a later DO no longer
  changes). So a leg's exit speed follows the previous leg's limits with only its first DO
  item applied (:func:`limits_at_setup`), as the SITL flights' DataFlash logs and speeds
  show (BENCHMARKS.md, "Moved from code comments").
- **Mission protocol** (``MissionItemProtocol``, ``AP_Mission``): upload items are asked
  for with the deprecated MISSION_REQUEST, again after 1 s of silence, and the upload is
  cancelled after 8 s; items are stored as they arrive, so a failed upload leaves a half
  mission behind; an item that was not asked for gets MAV_MISSION_INVALID_SEQUENCE and the
  transfer stays open, and once a transfer is over a re-sent item gets no answer. While
  booting, MISSION_COUNT gets MAV_MISSION_NO_SPACE. A location's altitude is stored in
  whole centimetres, truncated (:func:`missions.geodesy.ardupilot_altitude`); a command
  without a location sent in frame MISSION reads back in frame GLOBAL
  (:func:`missions.mavlink.messages.ardupilot_readback` says how every item reads back).
- **Parameter protocol** (``GCS_Param.cpp``, ``AP_Param::set_float``): PARAM_SET and
  PARAM_REQUEST_READ are answered with PARAM_VALUE holding the value now held (an integer
  parameter takes the float plus 0.01 away from zero, truncated and clamped; NaN and
  infinity are ignored); **an unknown name gets no answer at all**.
- **Parameters** (:class:`ArduCopterSettings`, written to each drone's ``.parm`` and
  checked on the vehicle at upload). BARO_GND_TEMP is deliberately absent: changing it on a
  powered vehicle makes its altitude estimate jump (BENCHMARKS.md, "Moved from code
  comments"); only a defaults file, read before the barometers calibrate, may set it.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

from missions.autopilots.spline import AccelLimits, SpeedLimits, Tracking

#: ArduCopter ignores DO_CHANGE_SPEED ground speeds below this (AC_WPNav's
#: WPNAV_WP_SPEED_MIN, 20 cm/s in Copter 4.5) [m/s].
MIN_GROUND_SPEED = 0.20
#: ArduCopter's flight modes (HEARTBEAT custom_mode) that executions command or watch for.
COPTER_MODES = {
    "STABILIZE": 0,
    "ALT_HOLD": 2,
    "AUTO": 3,
    "GUIDED": 4,
    "LOITER": 5,
    "RTL": 6,
    "LAND": 9,
    "BRAKE": 17,
}
#: The EKF's height source (EK3_SRC1_POSZ) and its value for each source a position-error
#: model may name (:mod:`missions.position_error`); ArduCopter's default is the barometer.
HEIGHT_SOURCE_PARAMETER = "EK3_SRC1_POSZ"
HEIGHT_SOURCES = {"barometer": 1, "gnss": 3}
#: GUID_TIMEOUT [s]: a GUIDED (or NAV_SCRIPT_TIME) vehicle without a new target for this
#: long zeroes its target's velocity and acceleration and holds; until then it moves the
#: target on with the last ones (default 3 s: 1.5 m at 0.5 m/s).
TARGET_TIMEOUT = 0.5
#: WPNAV_ACCEL and WPNAV_ACCEL_Z bounds (ArduCopter's parameter ranges) [m/s^2].
ACCEL_RANGE = (0.5, 5.0)
#: The order of the DO_CHANGE_SPEED items before a leg (``missions.export.builder``): ground,
#: climb, descent speed; a limit gets an item when it changes by more than
#: :data:`LIMIT_TOLERANCE` (relative).
SPEED_ORDER = ("horizontal", "up", "down")
LIMIT_TOLERANCE = 1e-6


def changed_limits(previous: SpeedLimits, limits: SpeedLimits) -> tuple[str, ...]:
    """The limits of ``limits`` that get a DO_CHANGE_SPEED item after ``previous``, in
    :data:`SPEED_ORDER`."""
    return tuple(
        name
        for name in SPEED_ORDER
        if abs(getattr(limits, name) - getattr(previous, name))
        > LIMIT_TOLERANCE * max(getattr(limits, name), getattr(previous, name))
    )


def limits_at_setup(previous: SpeedLimits, limits: SpeedLimits) -> SpeedLimits:
    """The limits a leg flown with ``limits`` after a leg flown with ``previous`` is set up
    with: ``previous`` with only the first changed limit applied (module docstring)."""
    changed = changed_limits(previous, limits)
    if not changed:
        return limits
    return replace(previous, **{changed[0]: getattr(limits, changed[0])})


@dataclass(frozen=True)
class ArduCopterSettings:
    """The navigation parameters a plan assumes on every drone (SI units here; the
    ``.parm`` file has ArduPilot's)."""

    accel: float = 0.5  #: WPNAV_ACCEL [m/s^2]
    accel_z: float = 0.5  #: WPNAV_ACCEL_Z [m/s^2]
    speed: float = 5.0  #: WPNAV_SPEED [m/s], the ground speed before the first DO
    speed_up: float = 2.5  #: WPNAV_SPEED_UP [m/s]
    speed_down: float = 1.5  #: WPNAV_SPEED_DN [m/s]
    jerk: float = 1.0  #: WPNAV_JERK [m/s^3]
    position_p: float = 1.0  #: PSC_POSXY_P
    velocity_p: float = 2.0  #: PSC_VELXY_P
    position_p_z: float = 1.0  #: PSC_POSZ_P
    velocity_p_z: float = 5.0  #: PSC_VELZ_P
    #: How fast the airframe reaches the horizontal and the vertical acceleration it is
    #: asked for [s] (not parameters: its attitude and thrust response), calibrated on the
    #: Rescue and Puzzle SITL flights of tests/missions/data, whose leg times it matches
    #: within a few per cent (BENCHMARKS.md, "Moved from code comments").
    accel_lag: float = 0.05
    accel_lag_z: float = 0.05

    @classmethod
    def for_acceleration(cls, max_acceleration: float) -> ArduCopterSettings:
        """Settings whose spline legs change speed at ``max_acceleration`` [m/s^2]: a
        spline uses half the kinematic limit along its tangent, so WPNAV_ACCEL and
        WPNAV_ACCEL_Z are twice it, within their ranges."""
        low, high = ACCEL_RANGE
        accel = min(max(2.0 * max_acceleration, low), high)
        return cls(accel=accel, accel_z=accel)

    @property
    def accel_limits(self) -> AccelLimits:
        return AccelLimits(self.accel, self.accel_z)

    @property
    def initial_speeds(self) -> SpeedLimits:
        return SpeedLimits(self.speed, self.speed_up, self.speed_down)

    @property
    def tracking(self) -> Tracking:
        """The vehicle's response and the leg clock's filter (AC_WPNav's time constant
        0.01 WPNAV_ACCEL [cm/s^2] / WPNAV_JERK [m/s^3])."""
        return Tracking(
            position_p=self.position_p,
            velocity_p=self.velocity_p,
            accel_lag=self.accel_lag,
            clock_tc=self.accel * 100.0 * 0.01 / self.jerk,
            position_p_z=self.position_p_z,
            velocity_p_z=self.velocity_p_z,
            accel_lag_z=self.accel_lag_z,
        )

    def parameters(self) -> dict[str, float]:
        """The ``.parm`` values, in ArduPilot's units."""
        return {
            "WPNAV_ACCEL": round(self.accel * 100.0, 3),
            "WPNAV_ACCEL_Z": round(self.accel_z * 100.0, 3),
            "WPNAV_SPEED": round(self.speed * 100.0, 3),
            "WPNAV_SPEED_UP": round(self.speed_up * 100.0, 3),
            "WPNAV_SPEED_DN": round(self.speed_down * 100.0, 3),
            "WPNAV_JERK": self.jerk,
            "PSC_POSXY_P": self.position_p,
            "PSC_VELXY_P": self.velocity_p,
            "PSC_POSZ_P": self.position_p_z,
            "PSC_VELZ_P": self.velocity_p_z,
            "WP_YAW_BEHAVIOR": 0.0,
        }

    @staticmethod
    def reasons() -> dict[str, str]:
        """Why the plan needs each parameter (the ``.parm`` file's comments)."""
        return {
            "WPNAV_ACCEL": "spline legs change speed at half of it: the plan's acceleration limit",
            "WPNAV_ACCEL_Z": "the same for climbs and descents",
            "WPNAV_SPEED": "ground speed limit until the first DO_CHANGE_SPEED (cm/s)",
            "WPNAV_SPEED_UP": "climb speed limit until the first climb DO_CHANGE_SPEED (cm/s)",
            "WPNAV_SPEED_DN": "descent speed limit until the first descent DO_CHANGE_SPEED",
            "WPNAV_JERK": "the leg clock's reaction to tracking lag (time constant ACCEL/JERK)",
            "PSC_POSXY_P": "the same on all three drones: it sets how much a lagging drone slows",
            "PSC_VELXY_P": "the tracking the plan's timing was modelled with",
            "PSC_POSZ_P": "the same vertically",
            "PSC_VELZ_P": "the same vertically",
            "WP_YAW_BEHAVIOR": "0: keep the heading; the default yaws at every corner",
        }


def team_parameters(height_source: str) -> tuple[dict[str, float], dict[str, str]]:
    """The parameters a drone of a team needs beyond its navigation (:class:`
    ArduCopterSettings`), and why: the position-error model's height source (none for
    ``any``), a short target timeout, and no lost-link failsafe of its own."""
    values: dict[str, float] = {"GUID_TIMEOUT": TARGET_TIMEOUT, "FS_GCS_ENABLE": 0.0}
    reasons = {
        "GUID_TIMEOUT": "a drone that hears no target for this long stops and holds (s): its "
        "last velocity would carry it away from the team",
        "FS_GCS_ENABLE": "0: a lost link must not make one drone act alone; the ground stops "
        "the team, or the onboard player keeps the clock",
    }
    if height_source in HEIGHT_SOURCES:
        values[HEIGHT_SOURCE_PARAMETER] = float(HEIGHT_SOURCES[height_source])
        reasons[HEIGHT_SOURCE_PARAMETER] = (
            f"{HEIGHT_SOURCES[height_source]}: {height_source} height, the position-error "
            "model's (the plan's clearance rests on it)"
        )
    return values, reasons
