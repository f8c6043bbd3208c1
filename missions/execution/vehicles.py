"""What the ground knows of each vehicle while it plays the plan: its clock, its frame and
its latest state, kept up to date by its link's reader thread.

- **Clock.** A vehicle stamps its messages with its boot time; SYSTEM_TIME pairs that with
  UNIX time (GPS time on a real vehicle; on SITL the simulation's, from one
  ``--start-time``). Common time = boot time + that offset, the one time base of the three
  (:mod:`missions.execution.group_clock`). The ground reads a vehicle's present from its
  recent stamped messages, each carried forward by the ground's clock times the
  simulation's speed-up: the largest of those (a message only ever arrives late, so the
  least delayed one says most), at most ``max_extrapolation`` past the last message (a
  simulator that stalls is not run ahead of).
- **Frame.** Targets go out in the vehicle's local NED frame (from its EKF origin). The
  trajectory is home-relative (:mod:`missions.trajectory.drone_trajectory`): north and east
  follow from where the task's ENU frame puts the EKF origin (GPS_GLOBAL_ORIGIN), in the
  vehicle's own metres (:mod:`missions.autopilots.location`), down from where the vehicle
  says its home is (HOME_POSITION), as the missions' relative altitudes do.
"""

from __future__ import annotations

import math
import threading
import time
from collections import deque
from typing import Any

import numpy as np
from numpy.typing import NDArray

from missions.autopilots.location import VehicleFrame
from missions.geodesy import DEGREE_UNIT
from missions.mavlink.transport import VehicleLink
from missions.options import GeodeticOrigin

#: How many recent stamped messages set a vehicle's present.
STAMPS = 40
#: What the execution reads from each vehicle.
TELEMETRY = (
    "SYSTEM_TIME",
    "HEARTBEAT",
    "LOCAL_POSITION_NED",
    "GPS_RAW_INT",
    "EKF_STATUS_REPORT",
    "HOME_POSITION",
    "GPS_GLOBAL_ORIGIN",
    "MISSION_CURRENT",
    "ATTITUDE",
    "NAV_CONTROLLER_OUTPUT",
)


GRAVITY = 9.80665  #: standard gravity [m/s^2]


class VehicleState:
    """One vehicle's clock, frame and latest telemetry (module docstring), fed by its
    link's reader thread; read from any thread."""

    def __init__(self, link: VehicleLink, speedup: float, max_extrapolation: float) -> None:
        self.link, self.speedup, self.max_extrapolation = link, speedup, max_extrapolation
        self._lock = threading.Lock()
        self.offset: float | None = None  #: common time - boot time [s]
        #: recent (boot time [s], ground monotonic time of receipt) pairs, newest last
        self._stamps: deque[tuple[float, float]] = deque(maxlen=STAMPS)
        self.mode: int | None = None
        self.system_status: int | None = None
        self.ekf_flags: int | None = None
        self.fix_type: int | None = None
        self.attitude: tuple[float, float] | None = None  #: roll, pitch [deg]
        #: roll, pitch its attitude controller asks for [deg] (ArduCopter reports them in
        #: NAV_CONTROLLER_OUTPUT)
        self.attitude_target: tuple[float, float] | None = None
        self.yaw = 0.0  #: [rad] from north
        self.position: tuple[float, NDArray[np.float64]] | None = None  #: (boot s, NED)
        self.velocity: NDArray[np.float64] | None = None  #: NED [m/s], of ``position``
        self.home_down: float | None = None
        self.origin: tuple[float, float] | None = None  #: EKF origin lat, lon [deg]
        self.heard: float | None = None  #: ground monotonic time of the last message
        self.mission_seq: int | None = None  #: the current mission item
        self.deaf = False  #: the ground no longer hears it (a lost link, injected)
        link.add_listener(TELEMETRY, self._on)

    def close(self) -> None:
        self.link.remove_listener(self._on)

    def _on(self, msg: Any) -> None:
        if self.deaf:
            return
        now = time.monotonic()
        kind = msg.get_type()
        with self._lock:
            self.heard = now
            boot = getattr(msg, "time_boot_ms", None)
            if boot is not None:
                self._stamps.append((boot / 1000.0, now))
            if kind == "SYSTEM_TIME" and msg.time_unix_usec > 0:
                self.offset = msg.time_unix_usec / 1e6 - msg.time_boot_ms / 1000.0
            elif kind == "HEARTBEAT":
                self.mode, self.system_status = msg.custom_mode, msg.system_status
            elif kind == "LOCAL_POSITION_NED":
                self.position = (msg.time_boot_ms / 1000.0, np.array([msg.x, msg.y, msg.z]))
                self.velocity = np.array([msg.vx, msg.vy, msg.vz])
            elif kind == "GPS_RAW_INT":
                self.fix_type = msg.fix_type
            elif kind == "ATTITUDE":
                self.attitude = (math.degrees(msg.roll), math.degrees(msg.pitch))
                self.yaw = float(msg.yaw)
            elif kind == "NAV_CONTROLLER_OUTPUT":
                self.attitude_target = (float(msg.nav_roll), float(msg.nav_pitch))
            elif kind == "EKF_STATUS_REPORT":
                self.ekf_flags = msg.flags
            elif kind == "HOME_POSITION":
                self.home_down = float(msg.z)
            elif kind == "MISSION_CURRENT":
                self.mission_seq = msg.seq
            elif kind == "GPS_GLOBAL_ORIGIN":
                self.origin = (msg.latitude * DEGREE_UNIT, msg.longitude * DEGREE_UNIT)

    def forget_clock_before(self, at: float) -> None:
        """Forget the readings of the vehicle's clock received before ground monotonic time
        ``at``: its pace changed then (a simulator's SIM_SPEEDUP), and a reading carried
        forward at the pace would misjudge its present."""
        with self._lock:
            recent = [stamp for stamp in self._stamps if stamp[1] >= at]
            self._stamps = deque(recent, maxlen=STAMPS)

    def boot_time(self, now: float | None = None, capped: bool = True) -> float | None:
        """The vehicle's boot time [s] at ground monotonic time ``now`` (module docstring;
        not ``capped``: carried forward however old its last message, what a clock that
        runs on whether heard or not reads)."""
        with self._lock:
            if not self._stamps:
                return None
            stamps = list(self._stamps)
        now = time.monotonic() if now is None else now
        carried = max(boot + (now - at) * self.speedup for boot, at in stamps)
        return min(carried, stamps[-1][0] + self.max_extrapolation) if capped else carried

    def common_time(self, now: float | None = None, capped: bool = True) -> float | None:
        boot = self.boot_time(now, capped)
        return None if boot is None or self.offset is None else boot + self.offset

    def attitude_error(self) -> float | None:
        """How far [deg] the vehicle's roll and pitch are from what its attitude controller
        asks for (the lean a load needs is in both): a drone that cannot follow its own
        controller has lost authority, a weak motor or a broken propeller."""
        with self._lock:
            if self.attitude is None or self.attitude_target is None:
                return None
            (roll, pitch), (roll_target, pitch_target) = self.attitude, self.attitude_target
        return math.hypot(roll - roll_target, pitch - pitch_target)

    def lean_acceleration(self) -> NDArray[np.float64] | None:
        """The horizontal acceleration [m/s^2, NED, down 0] the vehicle's lean gives it
        while its thrust holds its weight (drag neglected): where a drone that has lost
        authority is going before its velocity shows it."""
        with self._lock:
            if self.attitude is None:
                return None
            roll, pitch = (math.radians(angle) for angle in self.attitude)
            yaw = self.yaw
        # the thrust axis (body z) in NED, for ZYX Euler angles
        north = math.cos(roll) * math.sin(pitch) * math.cos(yaw) + math.sin(roll) * math.sin(yaw)
        east = math.cos(roll) * math.sin(pitch) * math.sin(yaw) - math.sin(roll) * math.cos(yaw)
        down = math.cos(roll) * math.cos(pitch)
        return -GRAVITY * np.array([north, east, 0.0]) / down

    def last_heard(self) -> float | None:
        """Common time of the newest stamped message: when the vehicle was last heard, on
        its own clock (a pause of the ground's makes every vehicle's older alike)."""
        with self._lock:
            if not self._stamps or self.offset is None:
                return None
            return self._stamps[-1][0] + self.offset

    def frame(self, origin: GeodeticOrigin, home_up: float) -> VehicleFrame | None:
        """The vehicle's frame in the task frame ``origin``, once it reported its EKF
        origin and home."""
        with self._lock:
            if self.origin is None or self.home_down is None:
                return None
            lat, lon = self.origin
            home_down = self.home_down
        return VehicleFrame.at(lat, lon, origin, home_down, home_up)

    def estimate(self) -> tuple[float, NDArray[np.float64]] | None:
        """(common time, local NED position) of the last position estimate."""
        with self._lock:
            if self.position is None or self.offset is None:
                return None
            boot, ned = self.position
            return boot + self.offset, ned.copy()

    def velocity_estimate(self) -> NDArray[np.float64] | None:
        """Local NED velocity [m/s] of the last position estimate."""
        with self._lock:
            return None if self.velocity is None else self.velocity.copy()
