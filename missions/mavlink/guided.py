"""Flying by targets: flight-mode changes, position targets, and the messages an onboard
player is told the group time with.

Messages are plain data (:data:`~missions.mavlink.messages.MessageSpec`), built here and
sent by whoever holds the link:

- :func:`set_mode`: MAV_CMD_DO_SET_MODE with a custom mode (ArduCopter's numbers,
  :data:`missions.autopilots.ardupilot.COPTER_MODES`);
- :func:`position_target`: SET_POSITION_TARGET_LOCAL_NED with position, velocity and
  acceleration in the vehicle's local NED frame (from its EKF origin). Acceleration only
  reaches ArduCopter through the LOCAL_NED message (the GLOBAL_INT one drops it);
- :func:`group_time`: DEBUG_FLOAT_ARRAY named ``GT``: a segment of the group clock in the
  vehicle's boot time (the onboard player's clock, a message ArduPilot itself ignores);
- :func:`request_message`: MAV_CMD_REQUEST_MESSAGE (HOME_POSITION, GPS_GLOBAL_ORIGIN).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from missions.mavlink.messages import Endpoint, MessageSpec, command_long, dialect, message_id

#: SET_POSITION_TARGET type_mask: position, velocity and acceleration used; yaw and yaw
#: rate ignored (the heading is held, WP_YAW_BEHAVIOR 0), acceleration not a force.
POSITION_VELOCITY_ACCELERATION = 1024 | 2048
#: MAV_MODE_FLAG_CUSTOM_MODE_ENABLED: base mode of a DO_SET_MODE with a custom mode.
CUSTOM_MODE_ENABLED = 1
#: The DEBUG_FLOAT_ARRAY name of group-time messages, and the array's length.
GROUP_TIME_NAME, GROUP_TIME_FLOATS = "GT", 58


def set_mode(custom_mode: int) -> tuple[int, tuple[float, ...]]:
    """(command, params) of MAV_CMD_DO_SET_MODE to ``custom_mode``, for
    :func:`~missions.mavlink.commands.send_command`."""
    return dialect.MAV_CMD_DO_SET_MODE, (float(CUSTOM_MODE_ENABLED), float(custom_mode))


def set_mode_message(custom_mode: int, target: Endpoint) -> MessageSpec:
    """The COMMAND_LONG of :func:`set_mode`, to send without waiting for its ack (sent to
    three vehicles back to back)."""
    command, params = set_mode(custom_mode)
    return command_long(command, target, params)


def position_target(
    boot_ms: int,
    target: Endpoint,
    position: ArrayLike,
    velocity: ArrayLike,
    acceleration: ArrayLike,
) -> MessageSpec:
    """SET_POSITION_TARGET_LOCAL_NED: ``position`` [m], ``velocity`` [m/s] and
    ``acceleration`` [m/s^2] in the vehicle's local NED frame, stamped with its boot time
    ``boot_ms``."""
    n, e, d = (float(v) for v in np.ravel(position))
    vn, ve, vd = (float(v) for v in np.ravel(velocity))
    an, ae, ad = (float(v) for v in np.ravel(acceleration))
    return (
        "SET_POSITION_TARGET_LOCAL_NED",
        {
            "time_boot_ms": int(boot_ms) & 0xFFFFFFFF,
            "target_system": target.system,
            "target_component": target.component,
            "coordinate_frame": dialect.MAV_FRAME_LOCAL_NED,
            "type_mask": POSITION_VELOCITY_ACCELERATION,
            "x": n,
            "y": e,
            "z": d,
            "vx": vn,
            "vy": ve,
            "vz": vd,
            "afx": an,
            "afy": ae,
            "afz": ad,
            "yaw": 0.0,
            "yaw_rate": 0.0,
        },
    )


def group_time(
    start_ms: int,
    tau0: float,
    rate: float,
    rate_end: float,
    ramp: float,
    sequence: int,
    lead: tuple[float, float] = (0.0, 0.0),
) -> MessageSpec:
    """DEBUG_FLOAT_ARRAY ``GT``: plan time ``tau0`` [s] at the vehicle's boot time
    ``start_ms``, the rate going from ``rate`` to ``rate_end`` over ``ramp`` [s], then
    staying; ``sequence`` orders the segments (:class:`~missions.execution.group_clock.
    Segment`, in the vehicle's clock); the player sets its targets ``lead`` (horizontal,
    vertical) [s] ahead of its present."""
    data = [float(tau0), float(rate), float(rate_end), float(ramp), float(sequence), *lead]
    return (
        "DEBUG_FLOAT_ARRAY",
        {
            "time_usec": int(start_ms),
            "name": GROUP_TIME_NAME.encode(),
            "array_id": 0,
            "data": data + [0.0] * (GROUP_TIME_FLOATS - len(data)),
        },
    )


def request_message(name: str) -> tuple[int, tuple[float, ...]]:
    """(command, params) of MAV_CMD_REQUEST_MESSAGE for message ``name``."""
    return dialect.MAV_CMD_REQUEST_MESSAGE, (float(message_id(name)),)
