"""Typed errors of the MAVLink transport: each names the vehicle and the protocol facts.

The MAVLink result codes are kept as numbers *and* names (``MAV_MISSION_RESULT``,
``MAV_RESULT``) so that a log line or an HTTP error body says exactly what the autopilot
answered, in the protocol's own words.
"""

from __future__ import annotations

from collections.abc import Mapping

from flycrane.errors import FieldProblem, FlyCraneError, InputError


class MavlinkError(FlyCraneError):
    """Root of the errors raised by ``missions.mavlink``."""


class ConnectionStringError(InputError, MavlinkError):
    """A connection string (``udpin:HOST:PORT``, ``/dev/ttyUSB0,57600``, ...) is invalid."""

    def __init__(self, address: str, reason: str) -> None:
        self.address = address
        super().__init__([FieldProblem("connection", f"{address!r}: {reason}")])


class MissionTransferError(MavlinkError):
    """The vehicle ended a mission operation with a MAV_MISSION_RESULT other than ACCEPTED.

    Attributes
    ----------
    vehicle : str
        The vehicle's name (its connection string unless named otherwise).
    operation : str
        ``"upload"``, ``"download"`` or ``"clear"``.
    result : int
        The MAV_MISSION_RESULT code of the vehicle's MISSION_ACK.
    result_name : str
        Its name, e.g. ``"MAV_MISSION_UNSUPPORTED_FRAME"``.
    seq : int or None
        The item the vehicle was answering about (the last one sent), if any.
    """

    def __init__(
        self, vehicle: str, operation: str, result: int, result_name: str, seq: int | None = None
    ) -> None:
        self.vehicle = vehicle
        self.operation = operation
        self.result = result
        self.result_name = result_name
        self.seq = seq
        at = f" (after item {seq})" if seq is not None else ""
        super().__init__(
            f"{vehicle}: mission {operation} refused with {result_name} ({result}){at}"
        )


class MavlinkTimeoutError(MavlinkError):
    """A vehicle did not answer within the stated time.

    Attributes
    ----------
    vehicle : str
        The vehicle's name.
    stage : str
        What was awaited, e.g. ``"HEARTBEAT"`` or ``"upload: MISSION_REQUEST for item 3"``.
    timeout_s : float
        How long it was awaited in total [s] (including every resend).
    """

    def __init__(self, vehicle: str, stage: str, timeout_s: float) -> None:
        self.vehicle = vehicle
        self.stage = stage
        self.timeout_s = timeout_s
        super().__init__(f"{vehicle}: no answer within {timeout_s:.3g} s waiting for {stage}")


class FinalAckTimeoutError(MavlinkTimeoutError):
    """Every item of an upload was requested and sent, but the vehicle's final MISSION_ACK
    never came: the mission may be complete on board, or not. Only a read-back can tell
    (ArduPilot does not answer a re-sent last item once its transfer is over)."""


class MissionVerificationError(MavlinkError):
    """The mission read back from a vehicle differs from the one uploaded.

    Attributes
    ----------
    vehicle : str
        The vehicle's name.
    seq : int or None
        The first differing item, or None when the item counts differ.
    field : str
        The first differing field of that item (``"count"`` for a count mismatch).
    expected, actual : object
        The uploaded and the read-back values of that field.
    """

    def __init__(
        self, vehicle: str, seq: int | None, field: str, expected: object, actual: object
    ) -> None:
        self.vehicle = vehicle
        self.seq = seq
        self.field = field
        self.expected = expected
        self.actual = actual
        where = f"item {seq} field {field}" if seq is not None else field
        super().__init__(
            f"{vehicle}: mission read back differs at {where}: "
            f"uploaded {expected!r}, vehicle has {actual!r}"
        )


class CommandRejectedError(MavlinkError):
    """A COMMAND_LONG was answered with a MAV_RESULT other than ACCEPTED.

    Attributes
    ----------
    vehicle : str
        The vehicle's name.
    command : int
        The MAV_CMD sent.
    result : int
        The MAV_RESULT code of the COMMAND_ACK.
    result_name : str
        Its name, e.g. ``"MAV_RESULT_DENIED"``.
    """

    def __init__(self, vehicle: str, command: int, result: int, result_name: str) -> None:
        self.vehicle = vehicle
        self.command = command
        self.result = result
        self.result_name = result_name
        super().__init__(f"{vehicle}: command {command} refused with {result_name} ({result})")


class FleetError(MavlinkError):
    """An operation on several vehicles failed on at least one of them.

    Attributes
    ----------
    operation : str
        What was attempted on every vehicle (``"upload"``, ``"arm"``, ...).
    failures : Mapping[str, MavlinkError]
        The error of every vehicle that failed, by vehicle name.
    succeeded : tuple[str, ...]
        The vehicles on which it succeeded.
    """

    def __init__(
        self, operation: str, failures: Mapping[str, MavlinkError], succeeded: tuple[str, ...]
    ) -> None:
        self.operation = operation
        self.failures = dict(failures)
        self.succeeded = succeeded
        details = "; ".join(str(error) for error in self.failures.values())
        super().__init__(
            f"{operation} failed on {len(self.failures)} of "
            f"{len(self.failures) + len(succeeded)} vehicles: {details}"
        )


class ParameterError(MavlinkError):
    """A vehicle parameter is not what the mission assumes.

    Attributes
    ----------
    vehicle : str
        The vehicle's name.
    name : str
        The parameter, e.g. ``"WPNAV_JERK"``.
    expected : float
        The value the mission's ``.parm`` file asks for.
    found : float | None
        The vehicle's value (None if it never answered for this parameter).
    """

    def __init__(self, vehicle: str, name: str, expected: float, found: float | None) -> None:
        self.vehicle = vehicle
        self.name = name
        self.expected = expected
        self.found = found
        has = "does not answer for it" if found is None else f"has {found:g}"
        super().__init__(f"{vehicle}: parameter {name} should be {expected:g}, the vehicle {has}")
