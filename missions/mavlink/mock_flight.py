"""Kinematic flight of a mission in simulated time, for the mock autopilot.

Not a flight dynamics model: a point that follows the mission's legs with a speed profile,
enough to check timing and geometry of multi-drone missions.

- **Time.** The mock autopilot steps the flight on a shared
  :class:`~missions.mavlink.sim_clock.SimClock`; mocks that share one clock share one epoch,
  so their timestamps (``time_boot_ms``) compare directly. UTC for NAV_DELAY is
  ``epoch_utc`` plus simulated time (plus a per-vehicle offset, to imitate vehicles whose
  clocks disagree, design.md section 9).
- **Space.** Positions are local ENU metres about a fixed origin (the configured start
  position); geodetic <-> ENU goes through pymap3d.
- **Commands.** Altitudes are flown as ArduPilot stores them, in whole centimetres
  (:func:`~missions.geodesy.ardupilot_altitude`; a download still returns the items as
  uploaded). NAV_TAKEOFF climbs vertically to the item altitude. NAV_WAYPOINT flies the
  straight 3-D line to the item at the current speed, with the along-track speed changing at
  most ``max_accel_mps2``; param1 is the hold time [s] at the waypoint. DO_CHANGE_SPEED
  sets the speed (param2 [m/s]; param1 0/1 horizontal, 2 climb, 3 descent) from the next
  leg on (do-commands between two nav items take effect when the leg to the second one
  starts, as ArduPilot's AP_Mission runs them); a horizontal speed below
  ``min_ground_speed_mps`` is ignored, as ArduCopter's AC_WPNav does (WPNAV_WP_SPEED_MIN,
  20 cm/s up to Copter 4.5). NAV_DELAY waits param1 seconds, or with
  param1 = -1 until the UTC time of day param2:param3:param4 (hour:minute:second, -1 to
  ignore the hour or minute; ArduPilot's AP_RTC rule: the next such time, so a time just
  past waits a day). The specification has a 1 s resolution (no fraction of a second can be
  given); the release happens at the exact second. NAV_LOITER_UNLIM holds forever; NAV_LAND
  descends at the land speed and disarms on touchdown.
- **Imperfections** (:class:`Imperfections`): start delay, a scale on every speed, a
  slow-down at waypoints (the speed through a waypoint drops by that fraction, 1 = stop, as
  ArduCopter decelerates around waypoints), and Gaussian position noise on what is reported
  (not on the state).

Simplification: the acceleration bound acts along the track only; a change of direction at
a waypoint is instantaneous.
"""

from __future__ import annotations

import datetime as dt
import math
from collections.abc import Generator, Sequence
from dataclasses import dataclass

import numpy as np
import pymap3d

from flycrane.errors import FieldProblem, InputError
from missions.geodesy import ardupilot_altitude
from missions.items import MavCmd, MissionItem

#: The commands the mock flies; anything else is refused at upload (MAV_MISSION_UNSUPPORTED).
NAV_COMMANDS = frozenset(
    {
        MavCmd.NAV_WAYPOINT,
        MavCmd.NAV_LOITER_UNLIM,
        MavCmd.NAV_LAND,
        MavCmd.NAV_TAKEOFF,
        MavCmd.NAV_DELAY,
    }
)
SUPPORTED_COMMANDS = NAV_COMMANDS | {MavCmd.DO_CHANGE_SPEED}
#: Nav commands whose x/y/z are a location.
LOCATION_COMMANDS = frozenset(
    {MavCmd.NAV_WAYPOINT, MavCmd.NAV_LOITER_UNLIM, MavCmd.NAV_LAND, MavCmd.NAV_TAKEOFF}
)
RELATIVE_ALT_FRAMES = frozenset({3, 6})

#: Below this height [m] the vehicle counts as on the ground.
GROUND_CLEARANCE_M = 0.05


def _positive(owner: str, **values: float) -> None:
    problems = [FieldProblem(k, f"must be > 0, got {v}") for k, v in values.items() if not v > 0]
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
        if problems:
            raise InputError(problems, source="Geodetic")


@dataclass(frozen=True)
class Dynamics:
    """Speed and acceleration limits; defaults are ArduCopter's (WPNAV_*, LAND_SPEED)."""

    cruise_speed_mps: float = 5.0
    max_accel_mps2: float = 2.5
    climb_speed_mps: float = 2.5
    descent_speed_mps: float = 1.5
    land_speed_mps: float = 0.5
    min_ground_speed_mps: float = 0.2  #: smaller DO_CHANGE_SPEED ground speeds are ignored

    def __post_init__(self) -> None:
        _positive("Dynamics", **{k: getattr(self, k) for k in self.__dataclass_fields__})


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
        if self.start_delay_s < 0:
            problems.append(FieldProblem("start_delay_s", f"must be >= 0: {self.start_delay_s}"))
        if not self.speed_scale > 0:
            problems.append(FieldProblem("speed_scale", f"must be > 0: {self.speed_scale}"))
        if not 0.0 <= self.waypoint_slowdown <= 1.0:
            problems.append(
                FieldProblem("waypoint_slowdown", f"must be in [0, 1]: {self.waypoint_slowdown}")
            )
        if self.position_noise_m < 0:
            problems.append(
                FieldProblem("position_noise_m", f"must be >= 0: {self.position_noise_m}")
            )
        if problems:
            raise InputError(problems, source="Imperfections")


def seconds_until_utc(now_utc: float, hour: int, minute: int, second: int) -> float:
    """Seconds from POSIX time ``now_utc`` to the next UTC time of day hour:minute:second.

    As ArduPilot's AP_RTC: the largest field that is not -1 sets the period (a day for the
    hour, an hour for the minute, a minute for the second); smaller fields at -1 count as 0;
    a time already past waits one period. All -1 means no wait.
    """
    if hour < 0 and minute < 0 and second < 0:
        return 0.0
    now = dt.datetime.fromtimestamp(now_utc, tz=dt.UTC)
    if hour >= 0:
        period = dt.timedelta(days=1)
        target = now.replace(hour=hour, minute=max(minute, 0), second=max(second, 0))
    elif minute >= 0:
        period = dt.timedelta(hours=1)
        target = now.replace(minute=minute, second=max(second, 0))
    else:
        period = dt.timedelta(minutes=1)
        target = now.replace(second=second)
    target = target.replace(microsecond=0)
    if target < now:
        target += period
    return (target - now).total_seconds()


@dataclass(frozen=True)
class FlightEvent:
    """Something the autopilot reports: ``"current"`` (item started) or ``"reached"``."""

    kind: str
    seq: int


@dataclass(frozen=True)
class SpeedProfile:
    """Along-track motion over one leg: the speed ramps at +-``accel`` from ``v_in`` to
    ``v_peak``, holds it for ``cruise_s``, and ramps to ``v_out`` [m, m/s, m/s^2, s]."""

    length: float
    v_in: float
    v_peak: float
    v_out: float
    accel: float
    cruise_s: float

    @classmethod
    def plan(
        cls, length: float, v_in: float, cruise: float, v_exit: float, accel: float
    ) -> SpeedProfile:
        """The fastest profile entering at ``v_in`` that never exceeds ``cruise`` (unless it
        enters faster and must first slow down) and passes the end at ``v_exit``; if the leg
        is too short to reach ``v_exit``, it ends at the speed the ramp reaches."""
        reach = 2.0 * accel * length
        if v_in**2 >= v_exit**2 + reach:  # cannot slow down to v_exit: brake all the way
            return cls(length, v_in, v_in, math.sqrt(v_in**2 - reach), accel, 0.0)
        if v_exit**2 >= v_in**2 + reach:  # cannot speed up to v_exit: accelerate all the way
            return cls(length, v_in, v_in, math.sqrt(v_in**2 + reach), accel, 0.0)
        # the triangle's apex, or cruise; entering above cruise, the apex exceeds v_in and
        # the profile slows down to cruise first
        peak = min(cruise, math.sqrt((reach + v_in**2 + v_exit**2) / 2.0))
        ramps = (abs(peak**2 - v_in**2) + abs(peak**2 - v_exit**2)) / (2.0 * accel)
        return cls(length, v_in, peak, v_exit, accel, max(length - ramps, 0.0) / peak)

    def _ramp(self, v_from: float, v_to: float) -> tuple[float, float]:
        duration = abs(v_to - v_from) / self.accel
        return duration, 0.5 * (v_from + v_to) * duration

    @property
    def duration(self) -> float:
        return (abs(self.v_peak - self.v_in) + abs(self.v_peak - self.v_out)) / self.accel + (
            self.cruise_s
        )

    def at(self, t: float) -> tuple[float, float]:
        """Distance along the leg [m] and speed [m/s] at ``t`` [s] after its start."""
        t1, d1 = self._ramp(self.v_in, self.v_peak)
        t2, t3 = self.cruise_s, abs(self.v_peak - self.v_out) / self.accel
        if t < t1:
            change = (1.0 if self.v_peak >= self.v_in else -1.0) * self.accel
            return self.v_in * t + 0.5 * change * t * t, self.v_in + change * t
        if t < t1 + t2:
            return d1 + self.v_peak * (t - t1), self.v_peak
        tau = min(t - t1 - t2, t3)
        sign = 1.0 if self.v_out >= self.v_peak else -1.0
        distance = d1 + self.v_peak * t2 + self.v_peak * tau + 0.5 * sign * self.accel * tau**2
        return min(distance, self.length), self.v_peak + sign * self.accel * tau


#: A phase of the flight: receives each step's duration [s], returns the time left over in
#: the step in which it ended [s], so that the next phase starts at the exact instant.
Phase = Generator[None, float, float]


class KinematicFlight:
    """State and mission execution of one vehicle (module docstring).

    Motion is exact, not integrated: each leg follows its :class:`SpeedProfile` in
    continuous time, and a phase that ends inside a simulation step hands the rest of the
    step to the next one. Steps only decide when the state is sampled.

    Parameters
    ----------
    origin : Geodetic
        The ENU origin and start position (on the ground).
    dynamics, imperfections
        See :class:`Dynamics`, :class:`Imperfections`.
    epoch_utc : float
        POSIX time [s] at simulated time 0 (:attr:`~missions.mavlink.sim_clock.SimClock.epoch_utc`).
    """

    def __init__(
        self,
        origin: Geodetic,
        dynamics: Dynamics,
        imperfections: Imperfections,
        epoch_utc: float,
    ) -> None:
        self.origin = origin
        self.epoch_utc = epoch_utc
        self.dynamics = dynamics
        self.imperfections = imperfections
        self.position = np.zeros(3)  #: ENU [m]
        self.velocity = np.zeros(3)  #: ENU [m/s]
        self.landed_disarm = False  #: set when NAV_LAND touched down (the autopilot disarms)
        self.finished = False
        self._speed = 0.0  # along-track speed carried from one leg into the next [m/s]
        self._cruise = dynamics.cruise_speed_mps
        self._climb = dynamics.climb_speed_mps
        self._descent = dynamics.descent_speed_mps
        self._program: Generator[None, float, None] | None = None
        self._events: list[FlightEvent] = []
        self._time = 0.0
        self._rng = np.random.default_rng(imperfections.seed)

    @property
    def running(self) -> bool:
        return self._program is not None and not self.finished

    @property
    def on_ground(self) -> bool:
        return self.position[2] <= GROUND_CLEARANCE_M

    def start(self, items: Sequence[MissionItem], first_seq: int, home_alt_m: float) -> None:
        """Fly ``items`` from ``first_seq`` (seq 0 is home and never flown) from the next
        step on; relative altitudes are above ``home_alt_m`` (AMSL)."""
        self._cruise = self.dynamics.cruise_speed_mps
        self._climb = self.dynamics.climb_speed_mps
        self._descent = self.dynamics.descent_speed_mps
        self.finished = False
        self.landed_disarm = False
        self._program = self._execute(tuple(items), max(first_seq, 1), home_alt_m)
        next(self._program)

    def stop(self) -> None:
        self._program = None
        self.velocity[:] = 0.0
        self._speed = 0.0

    def step(self, now: float, dt_s: float) -> list[FlightEvent]:
        """Advance by one step of ``dt_s`` ending at ``now`` [s]; the events of that step."""
        self._time = now
        if self._program is not None and not self.finished:
            try:
                self._program.send(dt_s)
            except StopIteration:  # the last item is done
                self.finished = True
        events, self._events = self._events, []
        return events

    def enu_from_item(self, item: MissionItem, home_alt_m: float) -> np.ndarray:
        """ENU [m] of a location item (x = y = 0 keeps the current horizontal position)."""
        z = float(ardupilot_altitude(item.z))  # whole centimetres, as AP_Mission stores them
        alt = z + home_alt_m if int(item.frame) in RELATIVE_ALT_FRAMES else z
        if item.x == 0 and item.y == 0:
            e, n = self.position[0], self.position[1]
            u = alt - self.origin.alt_m
        else:
            e, n, u = pymap3d.geodetic2enu(
                item.x * 1e-7,
                item.y * 1e-7,
                alt,
                self.origin.lat_deg,
                self.origin.lon_deg,
                self.origin.alt_m,
            )
        return np.array([e, n, u], dtype=float)

    def reported_geodetic(self) -> tuple[float, float, float]:
        """(lat [deg], lon [deg], alt AMSL [m]) of the position with the configured noise."""
        enu = self.position
        sigma = self.imperfections.position_noise_m
        if sigma > 0:
            enu = enu + self._rng.normal(0.0, sigma, 3)
        lat, lon, alt = pymap3d.enu2geodetic(
            enu[0], enu[1], enu[2], self.origin.lat_deg, self.origin.lon_deg, self.origin.alt_m
        )
        return float(lat), float(lon), float(alt)

    # --- mission execution: generators that receive each step's dt ---------------------

    def _execute(
        self, items: tuple[MissionItem, ...], first: int, home_alt: float
    ) -> Generator[None, float, None]:
        carry = yield  # the first step's duration: all of it is mission time
        carry = yield from self._hold(self.imperfections.start_delay_s, carry)
        for seq in range(first, len(items)):
            item = items[seq]
            command = int(item.command)
            if command == MavCmd.DO_CHANGE_SPEED:
                self._change_speed(item)
                continue
            self._events.append(FlightEvent("current", seq))  # MISSION_CURRENT: nav items
            if command == MavCmd.NAV_TAKEOFF:
                altitude = self.enu_from_item(item, home_alt)[2]
                if self.position[2] < altitude:
                    top = np.array([*self.position[:2], altitude])
                    carry = yield from self._fly(top, self._climb, 0.0, carry)
            elif command == MavCmd.NAV_WAYPOINT:
                target = self.enu_from_item(item, home_alt)
                through = 1.0 - self.imperfections.waypoint_slowdown
                exit_fraction = through if self._passes_through(items, seq) else 0.0
                carry = yield from self._fly(target, self._leg_speed(target), exit_fraction, carry)
                carry = yield from self._hold(max(item.param1, 0.0), carry)
            elif command == MavCmd.NAV_DELAY:
                carry = yield from self._hold(self._delay_s(item, carry), carry)
            elif command == MavCmd.NAV_LOITER_UNLIM:
                target = self.enu_from_item(item, home_alt)
                yield from self._fly(target, self._leg_speed(target), 0.0, carry)
                while True:
                    yield
            elif command == MavCmd.NAV_LAND:
                carry = yield from self._land(item, home_alt, carry)
            self._events.append(FlightEvent("reached", seq))

    def _change_speed(self, item: MissionItem) -> None:
        if item.param2 <= 0:  # -1 (or 0) means "no change" in MAV_CMD_DO_CHANGE_SPEED
            return
        if int(item.param1) == 2:
            self._climb = item.param2
        elif int(item.param1) == 3:
            self._descent = item.param2
        elif item.param2 >= self.dynamics.min_ground_speed_mps:
            self._cruise = item.param2

    @staticmethod
    def _passes_through(items: tuple[MissionItem, ...], seq: int) -> bool:
        """Whether the vehicle flies on through waypoint ``seq`` (no hold, and the next nav
        item is another waypoint) rather than stopping there."""
        if items[seq].param1 > 0:
            return False
        following = (i for i in items[seq + 1 :] if int(i.command) in NAV_COMMANDS)
        nxt = next(following, None)
        return nxt is not None and int(nxt.command) == MavCmd.NAV_WAYPOINT

    def _leg_speed(self, target: np.ndarray) -> float:
        """Speed along a straight leg: the largest whose horizontal part stays within the
        cruise (ground) speed and whose vertical part within the climb or descent speed, as
        ArduCopter's S-curve track limits it (SCurve::calculate_track, kinematic_limit)
        [m/s]."""
        delta = target - self.position
        length = float(np.linalg.norm(delta))
        if length == 0:
            return self._cruise
        horizontal = float(np.linalg.norm(delta[:2])) / length
        vertical = float(delta[2]) / length
        limits = [self._cruise / horizontal] if horizontal > 1e-9 else []
        if vertical > 1e-9:
            limits.append(self._climb / vertical)
        elif vertical < -1e-9:
            limits.append(self._descent / -vertical)
        return min(limits)

    def _hold(self, duration: float, carry: float) -> Phase:
        """Stay put for ``duration`` [s]."""
        self._speed = 0.0 if duration > 0 else self._speed
        if duration > 0:
            self.velocity = np.zeros(3)
        elapsed = carry
        while elapsed < duration:
            elapsed += yield
        return elapsed - duration

    def _fly(self, target: np.ndarray, speed: float, exit_fraction: float, carry: float) -> Phase:
        """Straight line to ``target`` at ``speed`` [m/s] (before the speed scale), passing
        ``target`` at ``exit_fraction`` of that speed (:class:`SpeedProfile`)."""
        start = self.position.copy()
        delta = target - start
        length = float(np.linalg.norm(delta))
        if length < 1e-9:
            return carry
        direction = delta / length
        cruise = speed * self.imperfections.speed_scale
        profile = SpeedProfile.plan(
            length, self._speed, cruise, cruise * exit_fraction, self.dynamics.max_accel_mps2
        )
        duration = profile.duration
        elapsed = carry
        while elapsed < duration:
            along, self._speed = profile.at(elapsed)
            self.position = start + direction * along
            self.velocity = direction * self._speed
            elapsed += yield
        self.position = target.copy()
        self._speed = profile.v_out
        self.velocity = direction * self._speed
        return elapsed - duration

    def _land(self, item: MissionItem, home_alt: float, carry: float) -> Phase:
        if item.x != 0 or item.y != 0:
            above = self.enu_from_item(item, home_alt)
            above[2] = self.position[2]
            carry = yield from self._fly(above, self._leg_speed(above), 0.0, carry)
        ground = np.array([*self.position[:2], 0.0])
        carry = yield from self._fly(ground, self.dynamics.land_speed_mps, 0.0, carry)
        self.landed_disarm = True
        return carry

    def _delay_s(self, item: MissionItem, carry: float) -> float:
        """How long NAV_DELAY ``item`` holds from now (the instant ``carry`` before the end
        of the current step) [s]."""
        if item.param1 >= 0:
            return float(item.param1)
        now_utc = self.epoch_utc + self._time - carry + self.imperfections.clock_offset_s
        return seconds_until_utc(now_utc, int(item.param2), int(item.param3), int(item.param4))
