"""A mock ArduCopter on one MAVLink connection: protocol, commands, streams, kinematic flight.

One thread per mock runs a loop in simulated time (:class:`~.sim_clock.SimClock`): it
advances the flight one clock step at a time, in lock step with the other mocks on the same
clock, sends what is due (HEARTBEAT every ``heartbeat_interval_s``, requested streams,
mission events) and handles what arrives after every step and while it waits for the next.
Every period is simulated time, so a mock at speed-up 10 heartbeats at 10 Hz of wall time.

Behaviour copied from ArduCopter 4.5 SITL where a ground station can tell the difference
(design.md section 9; the mission protocol itself is in :mod:`.mission_server`):

- GLOBAL_POSITION_INT and periodic MISSION_CURRENT only after a stream request:
  MAV_CMD_SET_MESSAGE_INTERVAL (either message) or REQUEST_DATA_STREAM (POSITION,
  EXTENDED_STATUS or ALL). MISSION_CURRENT is also sent whenever a nav item starts, and
  MISSION_ITEM_REACHED when one completes. ``time_boot_ms`` counts simulated milliseconds
  since the clock's epoch, so mocks sharing a clock have comparable timestamps.
- COMMAND_LONG MAV_CMD_COMPONENT_ARM_DISARM (refused while booting; disarm refused in the
  air unless forced with param2 = 21196). Arming makes the current position the home
  (:mod:`missions.autopilots.ardupilot`, "Home").
- MAV_CMD_MISSION_START: refused (DENIED) while disarmed, FAILED without a mission or when
  the first nav item is not a takeoff while on the ground ("Auto: Missing Takeoff Cmd");
  accepted without effect while the mission runs (ArduCopter's start_or_resume); it starts
  from the item set by MISSION_SET_CURRENT, else from seq 1, with the vehicle's parameters
  as they are then.
- MISSION_SET_CURRENT is confirmed by a MISSION_CURRENT naming the item; while the mission
  runs, the vehicle jumps there at once (:meth:`~.kinematic_flight.KinematicFlight.jump`), the
  release of the three drones from their hold (design.md section 9).
- Parameters: PARAM_SET, PARAM_REQUEST_READ and PARAM_REQUEST_LIST as ArduPilot answers
  them (:mod:`.parameters`); the navigation parameters fly the spline legs.
- Unknown commands: MAV_RESULT_UNSUPPORTED.
"""

from __future__ import annotations

import logging
import math
import threading
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import pymap3d

from flycrane.errors import FieldProblem, InputError
from missions.export.items import MavCmd, MissionItem
from missions.mavlink.messages import (
    Endpoint,
    MessageSpec,
    command_ack,
    dialect,
    global_position_int,
    heartbeat,
    message_id,
    mission_current,
    mission_item_reached,
    to_mavlink,
)
from missions.mavlink.transport import open_mavlink
from missions.mock.config import Dynamics, Geodetic, Imperfections
from missions.mock.faults import FaultInjection, FaultyChannel
from missions.mock.kinematic_flight import NAV_COMMANDS, KinematicFlight
from missions.mock.mission_server import MissionServer, home_item
from missions.mock.parameters import ParameterStore, settings_from_parameters
from missions.mock.sim_clock import SimClock

logger = logging.getLogger(__name__)

#: ArduPilot SITL's default location (CMAC, Canberra).
SITL_HOME = Geodetic(-35.363261, 149.165230, 584.0)
#: param2 of a disarm that must happen even in the air (MAVLink's magic number).
FORCE_DISARM = 21196.0
#: Interval a stream gets when SET_MESSAGE_INTERVAL asks for "the default" [s].
DEFAULT_STREAM_INTERVAL_S = 0.25
COPTER_MODE_STABILIZE, COPTER_MODE_AUTO = 0, 3
UNKNOWN_HEADING = 65535

_POSITION = message_id("GLOBAL_POSITION_INT")
_CURRENT = message_id("MISSION_CURRENT")
_STREAMS = {
    dialect.MAV_DATA_STREAM_ALL: (_POSITION, _CURRENT),
    dialect.MAV_DATA_STREAM_POSITION: (_POSITION,),
    dialect.MAV_DATA_STREAM_EXTENDED_STATUS: (_CURRENT,),
}
_MISSION_PROTOCOL = frozenset(
    {
        "MISSION_COUNT",
        "MISSION_ITEM_INT",
        "MISSION_ITEM",
        "MISSION_REQUEST_LIST",
        "MISSION_REQUEST_INT",
        "MISSION_REQUEST",
        "MISSION_CLEAR_ALL",
        "MISSION_ACK",
    }
)
_PARAMETER_PROTOCOL = frozenset({"PARAM_SET", "PARAM_REQUEST_READ", "PARAM_REQUEST_LIST"})


@dataclass(frozen=True)
class MockConfig:
    """One mock vehicle. Times are simulated seconds.

    ``boot_no_space_s`` is how long after start MISSION_COUNT gets MAV_MISSION_NO_SPACE and
    arming is refused (ArduCopter booting); ``max_items`` the largest mission accepted;
    ``request_int`` asks for upload items with MISSION_REQUEST_INT (PX4-like) instead of
    ArduCopter's MISSION_REQUEST; ``parameters`` replace ArduCopter's defaults at boot
    (:class:`~.parameters.ParameterStore`, ArduPilot's units).
    """

    system_id: int = 1
    component_id: int = 1
    home: Geodetic = SITL_HOME
    boot_no_space_s: float = 0.0
    heartbeat_interval_s: float = 1.0
    max_items: int = 700
    request_int: bool = False
    dynamics: Dynamics = field(default_factory=Dynamics)
    imperfections: Imperfections = field(default_factory=Imperfections)
    faults: FaultInjection = field(default_factory=FaultInjection)
    parameters: Mapping[str, float] = field(default_factory=dict)

    def __post_init__(self) -> None:
        ParameterStore(self.parameters)  # raises InputError naming an unknown parameter
        problems = []
        if not 1 <= self.system_id <= 255:
            problems.append(FieldProblem("system_id", f"must be in 1..255, got {self.system_id}"))
        if not 0 <= self.component_id <= 255:
            problems.append(
                FieldProblem("component_id", f"must be in 0..255, got {self.component_id}")
            )
        if not 0 < self.heartbeat_interval_s < math.inf:
            problems.append(
                FieldProblem(
                    "heartbeat_interval_s", f"must be > 0, got {self.heartbeat_interval_s}"
                )
            )
        if not 0 <= self.boot_no_space_s < math.inf:
            problems.append(
                FieldProblem(
                    "boot_no_space_s", f"must be finite and >= 0, got {self.boot_no_space_s}"
                )
            )
        if self.max_items < 1:
            problems.append(FieldProblem("max_items", f"must be >= 1, got {self.max_items}"))
        if problems:
            raise InputError(problems, source="MockConfig")


class MockAutopilot:
    """The vehicle side on ``address`` (module docstring). Use ``with`` or start()/stop().

    Parameters
    ----------
    address : str
        Connection string; ``udpin:127.0.0.1:PORT`` waits for a ground station to speak
        first, ``udpout:HOST:PORT`` sends to one (as SITL's ``--out``).
    config : MockConfig
    clock : SimClock, optional
        Share one between mocks to share the epoch (default: a new real-time clock).

    Raises
    ------
    OSError
        If the connection cannot be opened (e.g. the port is taken).
    """

    def __init__(
        self, address: str, config: MockConfig | None = None, clock: SimClock | None = None
    ) -> None:
        self.address = address
        self.config = config or MockConfig()
        self.clock = clock or SimClock()
        self.own = Endpoint(self.config.system_id, self.config.component_id)
        self._conn = open_mavlink(address, self.own)
        self._lock = threading.Lock()
        self._channel = FaultyChannel(self.config.faults)
        self.flight = KinematicFlight(
            self.config.home,
            self.config.dynamics,
            self.config.imperfections,
            self.clock.epoch_utc,
        )
        self._home = self.config.home
        self._server = MissionServer(
            self.own, self._home_item, self.config.max_items, self.config.request_int
        )
        self.parameters = ParameterStore(self.config.parameters)
        self.armed = False
        self._current = 0
        self._start_seq = 1
        # Simulated time advances in whole clock steps, counted, so that periodic messages
        # fall on exact multiples of their interval instead of drifting with float sums.
        self._vehicle = -1  # our id on the clock, once started
        self._steps = 0  # the last step done (clock steps since its epoch)
        self._first_step = 1  # heartbeats are counted from here
        self._time = self.clock.now()
        self._boot_until = self._time + self.config.boot_no_space_s
        self._intervals: dict[int, int] = {}  # message id -> interval [steps]
        self._phase: dict[int, int] = {}  # message id -> step of the first sample
        self._stop = threading.Event()
        self._thread = threading.Thread(
            target=self._run, name=f"mock-autopilot-{self.config.system_id}", daemon=True
        )

    @property
    def mission(self) -> tuple[MissionItem, ...]:
        """The stored mission as a download would return it."""
        with self._lock:
            return self._server.items

    @property
    def home(self) -> Geodetic:
        return self._home

    @property
    def streaming(self) -> frozenset[str]:
        """Names of the messages streamed periodically on request."""
        with self._lock:
            return frozenset(dialect.mavlink_map[i].msgname for i in self._intervals)

    def _steps_of(self, seconds: float) -> int:
        return max(1, round(seconds / self.clock.step_s))

    def start(self) -> MockAutopilot:
        with self._lock:
            self._vehicle, self._steps = self.clock.join()
            self._first_step = self._steps + 1
            self._time = self._steps * self.clock.step_s
            self._boot_until = self._time + self.config.boot_no_space_s
        self._thread.start()
        return self

    def stop(self) -> None:
        """Stop the loop (joined), leave the clock and close the connection. Idempotent."""
        self._stop.set()
        if self._thread.is_alive():
            self._thread.join(timeout=2.0)
        self.clock.leave(self._vehicle)
        self._conn.close()

    def __enter__(self) -> MockAutopilot:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.stop()

    # --- the loop ---------------------------------------------------------------------

    def _run(self) -> None:
        try:
            while not self._stop.is_set():
                wait = self.clock.may_begin(self._vehicle, self._steps + 1)
                if wait == 0.0:
                    self._step()
                try:
                    # after every step, and while waiting for the next: what arrived is
                    # handled at the simulated time of the last step
                    if self._conn.select(min(wait, 0.02)):
                        while (msg := self._conn.recv_msg()) is not None:
                            self._receive(msg)
                except (OSError, ValueError) as error:
                    if self._stop.is_set():
                        break  # closed under us on shutdown
                    logger.warning("mock %d: receive failed: %s", self.own.system, error)
                    self._stop.wait(0.05)
        finally:
            self.clock.leave(self._vehicle)  # peers must not wait for a dead loop

    def _step(self) -> None:
        """Advance the simulation by one clock step."""
        heartbeat_steps = self._steps_of(self.config.heartbeat_interval_s)
        with self._lock:
            self._steps += 1
            self._time = self._steps * self.clock.step_s
            self._advance(self.clock.step_s)
            if (self._steps - self._first_step) % heartbeat_steps == 0:
                self._send(self._heartbeat())
        self.clock.finished(self._vehicle, self._steps)

    def _send(self, spec: MessageSpec) -> None:
        for _ in range(self._channel.outgoing_copies()):
            self._conn.mav.send(to_mavlink(spec))

    def _receive(self, msg: Any) -> None:
        if msg.get_type() == "BAD_DATA":
            return
        target = getattr(msg, "target_system", None)
        if target not in (None, 0, self.own.system):
            return
        for _ in range(self._channel.incoming_copies()):
            with self._lock:
                for reply in self._handle(msg):
                    self._send(reply)

    def _advance(self, step: float) -> None:
        for event in self.flight.step(self._time, step):
            if event.kind == "current":
                self._current = event.seq
                self._send(mission_current(event.seq, len(self._server.items)))
            else:
                self._send(mission_item_reached(event.seq))
        if self.flight.landed_disarm and self.armed:
            self.armed = False  # ArduCopter disarms after an automatic landing
        if self.flight.finished:
            self._start_seq = 1
        for reply in self._server.tick(self._time):
            self._send(reply)
        for msg_id, interval in self._intervals.items():
            if (self._steps - self._phase[msg_id]) % interval == 0:
                self._send(
                    self._position()
                    if msg_id == _POSITION
                    else mission_current(self._current, len(self._server.items))
                )

    # --- what the vehicle says ----------------------------------------------------------

    def _booting(self) -> bool:
        return self._time < self._boot_until

    def _home_item(self) -> MissionItem:
        home = self._home
        return home_item(round(home.lat_deg * 1e7), round(home.lon_deg * 1e7), home.alt_m)

    def _heartbeat(self) -> MessageSpec:
        base_mode = dialect.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED
        if self.armed:
            base_mode |= dialect.MAV_MODE_FLAG_SAFETY_ARMED
        if self._booting():
            status = dialect.MAV_STATE_BOOT
        else:
            status = dialect.MAV_STATE_ACTIVE if self.armed else dialect.MAV_STATE_STANDBY
        mode = COPTER_MODE_AUTO if self.flight.running else COPTER_MODE_STABILIZE
        return heartbeat(
            dialect.MAV_TYPE_QUADROTOR,
            dialect.MAV_AUTOPILOT_ARDUPILOTMEGA,
            base_mode,
            mode,
            status,
        )

    def _position(self) -> MessageSpec:
        lat, lon, alt = self.flight.reported_geodetic()
        east, north, up = self.flight.reported_velocity()
        heading = UNKNOWN_HEADING
        if math.hypot(east, north) > 0.1:
            heading = round(math.degrees(math.atan2(east, north)) % 360.0 * 100) % 36000
        return global_position_int(
            time_boot_ms=round(self._time * 1000),
            lat_e7=round(lat * 1e7),
            lon_e7=round(lon * 1e7),
            alt_mm=round(alt * 1000),
            relative_alt_mm=round((alt - self._home.alt_m) * 1000),
            velocity_ned_cms=(round(north * 100), round(east * 100), round(-up * 100)),
            heading_cdeg=heading,
        )

    # --- what it does with what it hears ------------------------------------------------

    def _handle(self, msg: Any) -> list[MessageSpec]:
        kind = msg.get_type()
        sender = Endpoint(msg.get_srcSystem(), msg.get_srcComponent())
        if kind in _MISSION_PROTOCOL:
            return self._server.handle(msg, self._time, self._booting())
        if kind == "MISSION_SET_CURRENT":
            return self._set_current(msg.seq)
        if kind in _PARAMETER_PROTOCOL:
            return self.parameters.handle(msg)
        if kind == "COMMAND_LONG":
            result = self._command(msg)
            return [command_ack(msg.command, result, sender)]
        if kind == "REQUEST_DATA_STREAM":
            for msg_id in _STREAMS.get(msg.req_stream_id, ()):
                on = msg.start_stop and msg.req_message_rate > 0
                self._set_interval(msg_id, 1.0 / msg.req_message_rate if on else -1.0)
        return []

    def _set_current(self, seq: int) -> list[MessageSpec]:
        items = self._server.items
        if 1 <= seq < len(items):
            self._start_seq = seq
            if self.flight.running:
                self.flight.jump(items, seq, self._home.alt_m)
                self._current = seq  # until the nav item it runs to reports itself
        return [
            mission_current(self._current if self.flight.running else self._start_seq, len(items))
        ]

    def _set_interval(self, msg_id: int, interval_s: float) -> None:
        """Stream ``msg_id`` every ``interval_s`` (rounded to whole steps, 0 = default,
        negative = stop), the first sample at the next step."""
        if interval_s < 0:
            self._intervals.pop(msg_id, None)
            return
        self._intervals[msg_id] = self._steps_of(interval_s or DEFAULT_STREAM_INTERVAL_S)
        self._phase[msg_id] = self._steps + 1

    def _command(self, msg: Any) -> int:
        command = msg.command
        if command == dialect.MAV_CMD_COMPONENT_ARM_DISARM:
            return self._arm(msg.param1 == 1.0, force=msg.param2 == FORCE_DISARM)
        if command == MavCmd.MISSION_START:
            return self._mission_start()
        if command == dialect.MAV_CMD_SET_MESSAGE_INTERVAL:
            if int(msg.param1) not in (_POSITION, _CURRENT):
                return dialect.MAV_RESULT_FAILED
            self._set_interval(int(msg.param1), msg.param2 / 1e6 if msg.param2 > 0 else msg.param2)
            return dialect.MAV_RESULT_ACCEPTED
        return dialect.MAV_RESULT_UNSUPPORTED

    def _arm(self, arm: bool, force: bool) -> int:
        if not arm:
            if not (self.flight.on_ground or force):
                return dialect.MAV_RESULT_DENIED
            self.armed = False
            self.flight.stop()
            return dialect.MAV_RESULT_ACCEPTED
        if self._booting():
            return dialect.MAV_RESULT_TEMPORARILY_REJECTED
        if not self.armed:
            self.armed = True
            e, n, u = self.flight.position
            origin = self.config.home
            lat, lon, alt = pymap3d.enu2geodetic(
                e, n, u, origin.lat_deg, origin.lon_deg, origin.alt_m
            )
            self._home = Geodetic(float(lat), float(lon), float(alt))
        return dialect.MAV_RESULT_ACCEPTED

    def _mission_start(self) -> int:
        if not self.armed:
            return dialect.MAV_RESULT_DENIED
        if self.flight.running:
            return dialect.MAV_RESULT_ACCEPTED
        items = self._server.items
        navs = [i for i in items[self._start_seq :] if int(i.command) in NAV_COMMANDS]
        if not navs or (self.flight.on_ground and int(navs[0].command) != MavCmd.NAV_TAKEOFF):
            return dialect.MAV_RESULT_FAILED
        settings = settings_from_parameters(self.parameters.values)
        self.flight.start(items, self._start_seq, self._home.alt_m, settings)
        return dialect.MAV_RESULT_ACCEPTED
