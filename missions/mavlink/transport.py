"""Connections: connection strings, one reader thread per vehicle link, heartbeats.

A :class:`VehicleLink` owns one pymavlink connection and one thread. The thread reads every
message, hands it to whoever subscribed to its type (an :class:`Inbox` queue for the
request/answer protocols, a callback for the telemetry recorder), and sends the ground
station's HEARTBEAT once per ``RetryPolicy.gcs_heartbeat_interval_s``. Sending is allowed
from any thread (a lock keeps MAVLink sequence numbers and frames whole).

Every link speaks MAVLink 2 with the ``ardupilotmega`` dialect from the first byte on.
pymavlink would otherwise start in MAVLink 1 and switch *process-wide* (through an
environment variable) on the first MAVLink 2 frame it sees, which makes the behaviour of
one connection depend on the others.
"""

from __future__ import annotations

import logging
import queue
import re
import threading
import time
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from typing import Any

from pymavlink import mavutil

from missions.mavlink.errors import ConnectionStringError, MavlinkTimeoutError
from missions.mavlink.messages import (
    MAV_AUTOPILOT_INVALID,
    MAV_TYPE_GCS,
    Endpoint,
    MessageSpec,
    dialect,
    heartbeat,
    to_mavlink,
)
from missions.mavlink.policy import RetryPolicy

logger = logging.getLogger(__name__)

#: MAV_COMP_ID_MISSIONPLANNER: the component id ground stations use.
GCS_COMPONENT_ID = 190
#: Who we are on the link by default: system 255, the usual ground station id.
GROUND_STATION = Endpoint(255, GCS_COMPONENT_ID)

#: Fastest serial link taken [baud]: beyond any radio or USB-serial adapter's rate.
MAX_BAUD = 12_000_000

# ASCII digits only (re.ASCII): int() would read other scripts' digits as a port or a baud.
_NETWORK = re.compile(
    r"^(udpin|udpout|udp|tcpin|tcp):(?://)?(?P<host>[^:/]+):(?P<port>\d+)$", re.ASCII
)
_SERIAL = re.compile(
    r"^(?:serial:(?://)?)?(?P<device>/dev/[^,:]+|COM\d+)(?:[,:](?P<baud>\d+))?$", re.ASCII
)


@dataclass(frozen=True)
class ConnectionSpec:
    """A parsed connection string.

    ``kind`` is ``udpin`` (listen; ``udp`` is its alias, as in pymavlink), ``udpout`` (send
    to a listener), ``tcp`` (connect), ``tcpin`` (listen for one client) or ``serial``.
    """

    kind: str
    host: str = ""
    port: int = 0
    device: str = ""
    baud: int = 57600

    def mavutil_device(self) -> str:
        """The device string pymavlink's ``mavlink_connection`` expects."""
        if self.kind == "serial":
            return self.device
        return f"{self.kind}:{self.host}:{self.port}"


def parse_connection(address: str) -> ConnectionSpec:
    """Parse ``udpin:HOST:PORT``, ``udpout:HOST:PORT``, ``tcp:HOST:PORT``, ``tcpin:...``,
    ``serial:/dev/ttyUSB0:57600`` or ``/dev/ttyACM0,115200`` (MAVSDK's ``udpin://`` too).

    Raises
    ------
    ConnectionStringError
        For anything else, or a port outside 1..65535 (0 too for a listener: the system
        would pick a port nobody knows).
    """
    text = address.strip()
    network = _NETWORK.match(text)
    if network:
        kind = network.group(1)
        kind = "udpin" if kind == "udp" else kind
        port = int(network.group("port"))
        if not 1 <= port <= 65535:
            raise ConnectionStringError(address, f"port {port} outside 1..65535")
        return ConnectionSpec(kind=kind, host=network.group("host"), port=port)
    serial = _SERIAL.match(text)
    if serial:
        baud = int(serial.group("baud") or ConnectionSpec.baud)
        if not 1 <= baud <= MAX_BAUD:
            raise ConnectionStringError(address, f"baud {baud} outside 1..{MAX_BAUD}")
        return ConnectionSpec(kind="serial", device=serial.group("device"), baud=baud)
    raise ConnectionStringError(
        address,
        "expected udpin:HOST:PORT, udpout:HOST:PORT, tcp:HOST:PORT, tcpin:HOST:PORT "
        "or a serial device such as /dev/ttyUSB0,57600",
    )


def open_mavlink(address: str, source: Endpoint) -> Any:
    """Open a pymavlink connection speaking MAVLink 2 as ``source`` (module docstring).

    Raises
    ------
    ConnectionStringError
        If ``address`` does not parse.
    OSError
        If the socket or device cannot be opened (port in use, no such device, refused, a
        baud rate the device cannot take).
    """
    spec = parse_connection(address)
    conn = mavutil.mavlink_connection(
        spec.mavutil_device(),
        baud=spec.baud,
        source_system=source.system,
        source_component=source.component,
        autoreconnect=False,
        retries=1,
    )
    conn.mav = dialect.MAVLink(conn, srcSystem=source.system, srcComponent=source.component)
    conn.mav.robust_parsing = True
    conn.WIRE_PROTOCOL_VERSION = "2.0"
    conn.first_byte = False  # no auto-detection: we chose MAVLink 2 above
    return conn


@dataclass(frozen=True)
class VehicleInfo:
    """What a vehicle's HEARTBEAT says about it."""

    system_id: int
    component_id: int
    autopilot: int  #: MAV_AUTOPILOT
    vehicle_type: int  #: MAV_TYPE

    @property
    def endpoint(self) -> Endpoint:
        return Endpoint(self.system_id, self.component_id)


class Inbox:
    """Messages of some types from one link, queued until taken (use as a context manager)."""

    def __init__(self, link: VehicleLink, types: frozenset[str]) -> None:
        self.types = types
        self._link = link
        self._queue: queue.Queue[Any] = queue.Queue()

    def put(self, msg: Any) -> None:
        self._queue.put(msg)

    def get(self, timeout: float) -> Any | None:
        """The next message, or None after ``timeout`` [s] without one."""
        try:
            return self._queue.get(timeout=max(timeout, 0.0))
        except queue.Empty:
            return None

    def close(self) -> None:
        self._link.unsubscribe(self)

    def __enter__(self) -> Inbox:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


Listener = Callable[[Any], None]


class VehicleLink:
    """A ground-station link to one vehicle (module docstring). Close it, or use ``with``.

    Parameters
    ----------
    address : str
        Connection string (:func:`parse_connection`).
    policy : RetryPolicy
        Heartbeat timeout and GCS heartbeat interval come from here.
    name : str, optional
        How errors and logs name the vehicle (default: ``address``).
    source : Endpoint
        Our system/component id (default 255/190, a ground station).
    """

    def __init__(
        self,
        address: str,
        policy: RetryPolicy | None = None,
        name: str | None = None,
        source: Endpoint = GROUND_STATION,
    ) -> None:
        self.address = address
        self.name = name or address
        self.policy = policy or RetryPolicy()
        self.source = source
        self._conn = open_mavlink(address, source)
        self._send_lock = threading.Lock()
        self._subscribers_lock = threading.Lock()
        self._inboxes: list[Inbox] = []
        self._listeners: list[tuple[frozenset[str] | None, Listener]] = []
        self._info: VehicleInfo | None = None
        self._heard = threading.Event()
        self._muted = threading.Event()
        self._stop = threading.Event()
        self._thread = threading.Thread(
            target=self._run, name=f"mavlink-link-{self.name}", daemon=True
        )
        self._thread.start()

    @property
    def info(self) -> VehicleInfo:
        """The vehicle, once :meth:`wait_heartbeat` returned."""
        if self._info is None:
            raise RuntimeError(f"{self.name}: no heartbeat yet; call wait_heartbeat() first")
        return self._info

    @property
    def target(self) -> Endpoint:
        return self.info.endpoint

    def wait_heartbeat(self, timeout_s: float | None = None) -> VehicleInfo:
        """Wait for the vehicle's first HEARTBEAT (default ``policy.heartbeat_timeout_s``).

        Raises
        ------
        MavlinkTimeoutError
            With stage ``"HEARTBEAT"`` if none arrives in time.
        """
        timeout = self.policy.heartbeat_timeout_s if timeout_s is None else timeout_s
        if not self._heard.wait(timeout):
            raise MavlinkTimeoutError(self.name, "HEARTBEAT", timeout)
        return self.info

    def send(self, spec: MessageSpec) -> None:
        """Encode and send one message (thread-safe); nothing once :meth:`mute` was called."""
        if self._muted.is_set():
            return
        msg = to_mavlink(spec)
        with self._send_lock:
            self._conn.mav.send(msg)
        logger.debug("%s <- %s %s", self.name, spec[0], spec[1])

    def mute(self) -> None:
        """Send nothing more, heartbeats included, and keep receiving: the vehicle's view of
        a lost link (a fault a test injects)."""
        self._muted.set()

    def subscribe(self, types: Iterable[str]) -> Inbox:
        """Queue every later message of ``types`` from the vehicle until the inbox closes."""
        inbox = Inbox(self, frozenset(types))
        with self._subscribers_lock:
            self._inboxes.append(inbox)
        return inbox

    def unsubscribe(self, inbox: Inbox) -> None:
        with self._subscribers_lock:
            if inbox in self._inboxes:
                self._inboxes.remove(inbox)

    def add_listener(self, types: Iterable[str] | None, callback: Listener) -> None:
        """Call ``callback(msg)`` from the reader thread for every message of ``types``
        (None: every message from the vehicle).

        The callback must be quick and must not raise (it runs on the link's only reader).
        """
        with self._subscribers_lock:
            self._listeners.append((None if types is None else frozenset(types), callback))

    def remove_listener(self, callback: Listener) -> None:
        with self._subscribers_lock:
            self._listeners = [(t, c) for t, c in self._listeners if c is not callback]

    def close(self) -> None:
        """Stop the reader thread (joined) and close the connection. Idempotent."""
        self._stop.set()
        if self._thread.is_alive() and threading.current_thread() is not self._thread:
            self._thread.join(timeout=2.0)
        with self._send_lock:
            self._conn.close()

    def __enter__(self) -> VehicleLink:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def _is_vehicle(self, msg: Any) -> bool:
        return self._info is None or msg.get_srcSystem() == self._info.system_id

    def _dispatch(self, msg: Any) -> None:
        kind = msg.get_type()
        if kind == "BAD_DATA":
            return
        if kind == "HEARTBEAT" and self._info is None:
            if msg.type != MAV_TYPE_GCS and msg.autopilot != MAV_AUTOPILOT_INVALID:
                self._info = VehicleInfo(
                    msg.get_srcSystem(), msg.get_srcComponent(), msg.autopilot, msg.type
                )
                logger.info("%s: heartbeat from system %d", self.name, self._info.system_id)
                self._heard.set()
        if not self._is_vehicle(msg):
            return
        with self._subscribers_lock:
            inboxes = [i for i in self._inboxes if kind in i.types]
            listeners = [c for types, c in self._listeners if types is None or kind in types]
        for inbox in inboxes:
            inbox.put(msg)
        for callback in listeners:
            callback(msg)

    def _run(self) -> None:
        gcs_heartbeat = heartbeat(MAV_TYPE_GCS, MAV_AUTOPILOT_INVALID)
        next_heartbeat = time.monotonic()
        while not self._stop.is_set():
            now = time.monotonic()
            try:
                if now >= next_heartbeat:
                    self.send(gcs_heartbeat)
                    next_heartbeat = now + self.policy.gcs_heartbeat_interval_s
                if self._conn.select(min(0.05, max(next_heartbeat - now, 0.0))):
                    while (msg := self._conn.recv_msg()) is not None:
                        self._dispatch(msg)
            except (OSError, ValueError) as error:
                if self._stop.is_set():
                    break  # the socket was closed under us on shutdown
                logger.warning("%s: receive failed: %s", self.name, error)
                self._stop.wait(0.1)
