"""Kinematic flight of a mission in simulated time, for the mock autopilot.

Not a flight dynamics model: a point that follows the mission's legs with a speed profile,
enough to check timing and geometry of multi-drone missions.

- **Time.** The mock autopilot steps the flight on a shared
  :class:`~missions.mock.sim_clock.SimClock`; mocks that share one clock share one epoch,
  so their timestamps (``time_boot_ms``) compare directly. UTC for NAV_DELAY is
  ``epoch_utc`` plus simulated time (plus a per-vehicle offset, to imitate vehicles whose
  clocks disagree, design.md section 9).
- **Space.** Positions are local ENU metres about a fixed origin (the configured start
  position, on the ground); the vehicle stands :attr:`Dynamics.rest_height_m` above it, as
  SITL's does, and arming makes that home. Geodetic <-> ENU goes through pymap3d.
- **Commands.** Altitudes are flown as ArduPilot stores them, in whole centimetres
  (:func:`~missions.geodesy.ardupilot_altitude`). NAV_TAKEOFF climbs vertically to the item
  altitude. NAV_SPLINE_WAYPOINT legs are flown as ArduCopter 4.5 flies them
  (:mod:`.spline`, with the model of :mod:`missions.autopilots.spline`), with the
  vehicle's navigation parameters (:func:`~.parameters.settings_from_parameters`:
  WPNAV_SPEED, _UP and _DN are the speed limits until a DO_CHANGE_SPEED changes them,
  WPNAV_ACCEL and _ACCEL_Z the accelerations, PSC_* and WPNAV_JERK the tracking); param1
  is a hold time [s] at the waypoint. The position and velocity reported are the modelled
  vehicle's, which lags its target as a copter does (a few centimetres, more in braking);
  after the legs it settles onto the target with the position controller's time constant
  (1 / PSC_POSXY_P). NAV_WAYPOINT is the mock's own simpler leg (:mod:`.straight`), not
  ArduCopter's S-curve: the straight 3-D line to the item, with the along-track speed
  changing at most ``max_accel_mps2``, at :class:`Dynamics`' speeds until a DO_CHANGE_SPEED
  changes them; param1 is the hold time [s] at the waypoint. DO_CHANGE_SPEED sets a speed
  limit (param2 [m/s]) from the next leg on, by ArduCopter's rules
  (:mod:`missions.autopilots.ardupilot`, "Speeds": the ground-speed floor,
  ``min_ground_speed_mps`` here, and only the first DO item before a spline leg setting
  the leg up). NAV_DELAY waits param1 seconds, or with param1 = -1 until a UTC time of day
  (:func:`seconds_until_utc`); the specification has a 1 s resolution, and the release
  happens at the exact second. NAV_LOITER_UNLIM holds forever; NAV_LAND descends at the
  land speed and disarms on touchdown.
- **Jumps.** :meth:`KinematicFlight.jump` (MISSION_SET_CURRENT during a flight) runs the
  mission from the given item as ArduCopter does (:mod:`missions.autopilots.ardupilot`,
  "Start"); a spline leg after it starts from rest.
- **Imperfections** (:class:`Imperfections`): start delay (at every start or jump), a scale
  on every speed (spline legs: on their speed limits), a slow-down at straight waypoints
  (the speed through a waypoint drops by that fraction, 1 = stop, as ArduCopter decelerates
  around waypoints), and Gaussian position noise on what is reported (not on the state).

Simplifications of straight legs: the acceleration bound acts along the track only; a
change of direction at a waypoint is instantaneous. A spline leg followed by a straight one
stops at their waypoint.
"""

from __future__ import annotations

import datetime as dt
from collections.abc import Generator, Sequence
from dataclasses import dataclass, replace

import numpy as np
import pymap3d

from missions.autopilots.ardupilot import ArduCopterSettings
from missions.autopilots.spline import SpeedLimits, kinematic_limit
from missions.export.items import MavCmd, MissionItem
from missions.geodesy import ardupilot_altitude
from missions.mock.config import Dynamics, Geodetic, Imperfections
from missions.mock.parameters import ARDUCOPTER_DEFAULTS, settings_from_parameters
from missions.mock.spline import NextWaypoint, SplineLeg, SplineNavigator
from missions.mock.straight import SpeedProfile

#: The commands the mock flies; anything else is refused at upload (MAV_MISSION_UNSUPPORTED).
NAV_COMMANDS = frozenset(
    {
        MavCmd.NAV_WAYPOINT,
        MavCmd.NAV_SPLINE_WAYPOINT,
        MavCmd.NAV_LOITER_UNLIM,
        MavCmd.NAV_LAND,
        MavCmd.NAV_TAKEOFF,
        MavCmd.NAV_DELAY,
    }
)
SUPPORTED_COMMANDS = NAV_COMMANDS | {MavCmd.DO_CHANGE_SPEED}
#: Nav commands whose x/y/z are a location.
LOCATION_COMMANDS = frozenset(
    {
        MavCmd.NAV_WAYPOINT,
        MavCmd.NAV_SPLINE_WAYPOINT,
        MavCmd.NAV_LOITER_UNLIM,
        MavCmd.NAV_LAND,
        MavCmd.NAV_TAKEOFF,
    }
)
RELATIVE_ALT_FRAMES = frozenset({3, 6})

#: Below this height [m] the vehicle counts as on the ground.
GROUND_CLEARANCE_M = 0.05
#: DO_CHANGE_SPEED speed types (param1) and the limit each sets
#: (:mod:`missions.autopilots.ardupilot`, "Speeds").
_SPEED_TYPES = {0: "horizontal", 1: "horizontal", 2: "up", 3: "down"}


def default_settings() -> ArduCopterSettings:
    """The navigation model of a vehicle with ArduCopter's default parameters."""
    return settings_from_parameters({name: v for name, (v, _) in ARDUCOPTER_DEFAULTS.items()})


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
        POSIX time [s] at simulated time 0 (:attr:`~missions.mock.sim_clock.SimClock.epoch_utc`).
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
        #: ENU [m]: standing on the ground below the origin
        self.position = np.array([0.0, 0.0, dynamics.rest_height_m])
        self.velocity = np.zeros(3)  #: ENU [m/s]
        self.landed_disarm = False  #: set when NAV_LAND touched down (the autopilot disarms)
        self.finished = False
        self._speed = 0.0  # along-track speed carried from one leg into the next [m/s]
        # where the vehicle is against its target (spline legs: the tracking model's lag;
        # after them it settles with the position controller's time constant) [m, m/s]
        self._lag = np.zeros(3)
        self._lag_velocity = np.zeros(3)
        self._overrides: dict[str, float] = {}  # DO_CHANGE_SPEED limits so far [m/s]
        self._navigator = SplineNavigator(default_settings())
        self._program: Generator[None, float, None] | None = None
        self._events: list[FlightEvent] = []
        self._time = 0.0
        self._rng = np.random.default_rng(imperfections.seed)

    @property
    def running(self) -> bool:
        return self._program is not None and not self.finished

    @property
    def on_ground(self) -> bool:
        return self.position[2] <= self.dynamics.rest_height_m + GROUND_CLEARANCE_M

    def start(
        self,
        items: Sequence[MissionItem],
        first_seq: int,
        home_alt_m: float,
        settings: ArduCopterSettings | None = None,
    ) -> None:
        """Fly ``items`` from ``first_seq`` (seq 0 is home and never flown) from the next
        step on; relative altitudes are above ``home_alt_m`` (AMSL). ``settings``: the
        vehicle's navigation parameters (default: ArduCopter's defaults); speed limits
        start from them (spline legs) and from :class:`Dynamics` (straight legs)."""
        self._overrides = {}
        self._navigator = SplineNavigator(settings or default_settings())
        self.jump(items, first_seq, home_alt_m)

    def jump(self, items: Sequence[MissionItem], seq: int, home_alt_m: float) -> None:
        """Go on from ``seq`` from the next step on, keeping the speed limits in force
        (MISSION_SET_CURRENT during a flight, module docstring)."""
        self.finished = False
        self.landed_disarm = False
        self._navigator.stop()
        self._program = self._execute(tuple(items), max(seq, 1), home_alt_m)
        next(self._program)

    def stop(self) -> None:
        self._program = None
        self.velocity[:] = 0.0
        self._speed = 0.0
        self._navigator.stop()

    def step(self, now: float, dt_s: float) -> list[FlightEvent]:
        """Advance by one step of ``dt_s`` ending at ``now`` [s]; the events of that step."""
        self._time = now
        settle = np.exp(-dt_s * self._navigator.settings.position_p)
        self._lag, self._lag_velocity = self._lag * settle, self._lag_velocity * settle
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
        """(lat [deg], lon [deg], alt AMSL [m]) of the vehicle (its target and its lag),
        with the configured noise."""
        enu = self.position + self._lag
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
        # the limits a spline leg is set up with: those after the first DO item before it
        # (missions.autopilots.ardupilot, "Speeds")
        at_setup, first_do = dict(self._overrides), True
        for seq in range(first, len(items)):
            item = items[seq]
            command = int(item.command)
            if command == MavCmd.DO_CHANGE_SPEED:
                self._change_speed(item)
                if first_do:
                    at_setup, first_do = dict(self._overrides), False
                continue
            if first_do:
                at_setup = dict(self._overrides)
            first_do = True
            self._events.append(FlightEvent("current", seq))  # MISSION_CURRENT: nav items
            if command == MavCmd.NAV_SPLINE_WAYPOINT:
                carry = yield from self._spline(items, seq, home_alt, at_setup, carry)
                carry = yield from self._hold(max(item.param1, 0.0), carry)
                self._events.append(FlightEvent("reached", seq))
                continue
            self._navigator.stop()  # a spline leg after any other nav item starts at rest
            if command == MavCmd.NAV_TAKEOFF:
                altitude = self.enu_from_item(item, home_alt)[2]
                if self.position[2] < altitude:
                    top = np.array([*self.position[:2], altitude])
                    climb = self._limits(self._straight_base()).up
                    carry = yield from self._fly(top, climb, 0.0, carry)
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
        """ArduCopter's ``do_change_speed`` (its ``desired_speed_override``)."""
        if item.param2 <= 0:  # -1 (or 0) means "no change" in MAV_CMD_DO_CHANGE_SPEED
            return
        limit = _SPEED_TYPES.get(int(item.param1))
        if limit == "horizontal" and item.param2 < self.dynamics.min_ground_speed_mps:
            return
        if limit is not None:
            self._overrides[limit] = float(item.param2)

    def _spline_limits(self, overrides: dict[str, float]) -> SpeedLimits:
        """The vehicle's WPNAV_SPEED* with ``overrides``, times the speed scale."""
        limits = replace(self._navigator.settings.initial_speeds, **overrides)
        scale = self.imperfections.speed_scale
        return SpeedLimits(limits.horizontal * scale, limits.up * scale, limits.down * scale)

    def _straight_base(self) -> SpeedLimits:
        d = self.dynamics
        return SpeedLimits(d.cruise_speed_mps, d.climb_speed_mps, d.descent_speed_mps)

    def _limits(self, base: SpeedLimits) -> SpeedLimits:
        """``base`` with the DO_CHANGE_SPEED limits set so far."""
        return replace(base, **self._overrides)

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
        limits = self._limits(self._straight_base())
        delta = target - self.position
        if not np.any(delta):
            return limits.horizontal
        return kinematic_limit(delta, limits.horizontal, limits.up, limits.down)

    def _next_nav(
        self, items: tuple[MissionItem, ...], seq: int, home_alt: float, default: np.ndarray
    ) -> tuple[int, NextWaypoint] | None:
        """The first nav item after ``seq``: its seq and where it is (ArduCopter's
        ``loc_from_cmd``: a zero latitude and longitude, or altitude, stand for
        ``default``'s; an item without a location is at ``default``)."""
        for later in range(seq + 1, len(items)):
            item = items[later]
            if int(item.command) not in NAV_COMMANDS:
                continue
            position = default.copy()
            if int(item.command) in LOCATION_COMMANDS:
                located = self.enu_from_item(item, home_alt)
                if item.x != 0 or item.y != 0:
                    position[:2] = located[:2]
                if item.z != 0:
                    position[2] = located[2]
            return later, NextWaypoint(position, int(item.command) == MavCmd.NAV_SPLINE_WAYPOINT)
        return None

    def _spline(
        self,
        items: tuple[MissionItem, ...],
        seq: int,
        home_alt: float,
        at_setup: dict[str, float],
        carry: float,
    ) -> Phase:
        """The spline leg to waypoint ``seq`` (:class:`~.spline.SplineNavigator`)."""
        destination = self.enu_from_item(items[seq], home_alt)
        following = after = None
        if items[seq].param1 <= 0:  # a hold at the waypoint makes it a stop
            following = self._next_nav(items, seq, home_alt, destination)
        if following is not None and items[following[0]].param1 <= 0:
            after = self._next_nav(items, following[0], home_alt, following[1].position)
        leg = self._navigator.leg(
            self.position.copy(),
            destination,
            None if following is None else following[1],
            None if after is None else after[1],
            self._spline_limits(self._overrides),
            self._spline_limits(at_setup),
        )
        elapsed = carry
        while elapsed < leg.duration:
            self._follow(leg, elapsed)
            elapsed += yield
        self._follow(leg, leg.duration)
        self.position = destination
        self._speed = leg.exit_speed
        return elapsed - leg.duration

    def _follow(self, leg: SplineLeg, elapsed: float) -> None:
        """Target and vehicle ``elapsed`` [s] into a spline leg."""
        self.position, self.velocity = leg.at(elapsed)
        vehicle, velocity = leg.vehicle_at(elapsed)
        self._lag, self._lag_velocity = vehicle - self.position, velocity - self.velocity

    def reported_velocity(self) -> np.ndarray:
        """The vehicle's velocity (ENU m/s): its target's and its lag's."""
        return self.velocity + self._lag_velocity

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
        ground = np.array([*self.position[:2], self.dynamics.rest_height_m])
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
