"""The mock autopilot's parameters, answered as ArduCopter 4.5 answers them.

Pure logic, like :class:`~missions.mock.mission_server.MissionServer`:
:meth:`ParameterStore.handle` takes a received message and returns the messages to send.
It answers as ArduCopter does (:mod:`missions.autopilots.ardupilot`, "Parameter protocol":
the value held, in its native type, :func:`stored_value`; silence for an unknown name),
with ``param_index`` 65535 for a request by name and the index for one by index;
PARAM_REQUEST_LIST answers every parameter, by index.

The store holds the parameters a plan's ``.parm`` sets (``ArduCopterSettings.parameters``)
with ArduCopter 4.5.7's defaults, read from the binary (``docs/missions.md``);
:func:`settings_from_parameters` turns them into the model the mock flies spline legs with.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import numpy as np

from flycrane.errors import FieldProblem, InputError
from missions.autopilots.ardupilot import ArduCopterSettings
from missions.mavlink.messages import MessageSpec, dialect, float32, param_value

REAL32, INT8 = dialect.MAV_PARAM_TYPE_REAL32, dialect.MAV_PARAM_TYPE_INT8
#: MAV_PARAM_TYPE -> the integer type's range.
INTEGER_RANGES = {INT8: (-128, 127)}
#: ``param_index`` of an answer to a request by name (ArduPilot echoes the -1 it got,
#: which the uint16 field carries as 65535).
NO_INDEX = 65535
#: ArduCopter 4.5.7's defaults (value in ArduPilot's units, MAV_PARAM_TYPE).
ARDUCOPTER_DEFAULTS: dict[str, tuple[float, int]] = {
    "PSC_POSXY_P": (1.0, REAL32),
    "PSC_POSZ_P": (1.0, REAL32),
    "PSC_VELXY_P": (2.0, REAL32),
    "PSC_VELZ_P": (5.0, REAL32),
    "WPNAV_ACCEL": (250.0, REAL32),
    "WPNAV_ACCEL_Z": (100.0, REAL32),
    "WPNAV_JERK": (1.0, REAL32),
    "WPNAV_SPEED": (1000.0, REAL32),
    "WPNAV_SPEED_DN": (150.0, REAL32),
    "WPNAV_SPEED_UP": (250.0, REAL32),
    "WP_YAW_BEHAVIOR": (2.0, INT8),
    "GUID_TIMEOUT": (3.0, REAL32),
    "FS_GCS_ENABLE": (0.0, INT8),
    "EK3_SRC1_POSZ": (1.0, INT8),
}


def stored_value(value: float, param_type: int) -> float:
    """``value`` as a parameter of ``param_type`` holds it (``AP_Param::set_float``)."""
    if param_type not in INTEGER_RANGES:
        return float32(value)
    low, high = INTEGER_RANGES[param_type]
    nudged = float(np.float32(value) + np.float32(math.copysign(0.01, value)))
    return float(math.trunc(min(max(nudged, low), high)))


def settings_from_parameters(values: Mapping[str, float]) -> ArduCopterSettings:
    """The navigation model of a vehicle with these parameters (ArduPilot's units): the
    inverse of :meth:`ArduCopterSettings.parameters`; the airframe's response
    (``accel_lag``, ``accel_lag_z``) is not a parameter and keeps its calibrated value."""
    return ArduCopterSettings(
        accel=values["WPNAV_ACCEL"] / 100.0,
        accel_z=values["WPNAV_ACCEL_Z"] / 100.0,
        speed=values["WPNAV_SPEED"] / 100.0,
        speed_up=values["WPNAV_SPEED_UP"] / 100.0,
        speed_down=values["WPNAV_SPEED_DN"] / 100.0,
        jerk=values["WPNAV_JERK"],
        position_p=values["PSC_POSXY_P"],
        velocity_p=values["PSC_VELXY_P"],
        position_p_z=values["PSC_POSZ_P"],
        velocity_p_z=values["PSC_VELZ_P"],
    )


def _name(raw: Any) -> str:
    text = raw.decode("ascii", "replace") if isinstance(raw, bytes) else str(raw)
    return text.rstrip("\x00")


class ParameterStore:
    """One vehicle's parameters (module docstring).

    Parameters
    ----------
    overrides : Mapping[str, float]
        Values that replace the defaults at boot, as SITL's ``--defaults`` file does.

    Raises
    ------
    InputError
        If an override names a parameter the store does not have.
    """

    def __init__(self, overrides: Mapping[str, float] | None = None) -> None:
        overrides = dict(overrides or {})
        unknown = sorted(set(overrides) - set(ARDUCOPTER_DEFAULTS))
        if unknown:
            known = ", ".join(ARDUCOPTER_DEFAULTS)
            problems = [
                FieldProblem(f"parameters.{n}", f"unknown (known: {known})") for n in unknown
            ]
            raise InputError(problems, source="MockConfig")
        self._types = {name: kind for name, (_, kind) in ARDUCOPTER_DEFAULTS.items()}
        self._values = {
            name: stored_value(overrides.get(name, default), kind)
            for name, (default, kind) in ARDUCOPTER_DEFAULTS.items()
        }
        self._names = tuple(ARDUCOPTER_DEFAULTS)  # index order

    @property
    def values(self) -> dict[str, float]:
        return dict(self._values)

    def handle(self, msg: Any) -> list[MessageSpec]:
        """Answer one PARAM_SET, PARAM_REQUEST_READ or PARAM_REQUEST_LIST."""
        kind = msg.get_type()
        if kind == "PARAM_REQUEST_LIST":
            return [self._value(name, index) for index, name in enumerate(self._names)]
        if kind == "PARAM_REQUEST_READ" and msg.param_index >= 0:
            if msg.param_index >= len(self._names):
                return []
            return [self._value(self._names[msg.param_index], msg.param_index)]
        name = _name(msg.param_id)
        if name not in self._values:
            return []  # ArduPilot does not answer for a name it does not know
        if kind == "PARAM_SET":
            if not math.isfinite(msg.param_value):
                return []
            self._values[name] = stored_value(msg.param_value, self._types[name])
        return [self._value(name, NO_INDEX)]

    def _value(self, name: str, index: int) -> MessageSpec:
        return param_value(name, self._values[name], self._types[name], len(self._names), index)
