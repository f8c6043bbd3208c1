"""Vehicle parameters: read, set with read-back, and check a vehicle against a mission's
``.parm`` file.

PARAM_REQUEST_READ and PARAM_SET are both answered by PARAM_VALUE with the value the vehicle
holds afterwards; silence is re-sent per :class:`~missions.mavlink.policy.RetryPolicy`
(ArduCopter answers nothing for a name it does not know,
:mod:`missions.autopilots.ardupilot`). Values travel as float32 whatever the parameter's
type, so a value is "as expected" when it equals the expected one rounded to float32 to a
relative ``1e-6`` (integer parameters come back exact).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from functools import partial

from missions.mavlink.errors import ParameterError
from missions.mavlink.messages import MessageSpec, float32, param_request_read, param_set
from missions.mavlink.policy import RetryPolicy
from missions.mavlink.transport import VehicleLink

#: Relative tolerance of a float32 round trip.
RELATIVE_TOLERANCE = 1e-6


@dataclass(frozen=True)
class ParameterCheck:
    """One parameter on one vehicle against the value the plan assumes."""

    vehicle: str
    name: str
    expected: float
    found: float | None  #: None: the vehicle did not answer for it

    @property
    def ok(self) -> bool:
        return self.found is not None and same_value(self.expected, self.found)

    def error(self) -> ParameterError:
        return ParameterError(self.vehicle, self.name, self.expected, self.found)


def same_value(expected: float, found: float) -> bool:
    want = float32(expected)
    return math.isclose(want, found, rel_tol=RELATIVE_TOLERANCE, abs_tol=1e-9)


def _exchange(
    link: VehicleLink,
    name: str,
    spec_of: Callable[[], MessageSpec],
    policy: RetryPolicy,
    ends: float = math.inf,
) -> float | None:
    """Send ``spec_of()`` until a PARAM_VALUE for ``name`` answers; its value, or None (no
    answer, or none before ``ends``, a ``time.monotonic()`` value)."""
    with link.subscribe(("PARAM_VALUE",)) as inbox:
        for _ in range(policy.retries + 1):
            if time.monotonic() >= ends:
                break
            link.send(spec_of())
            until = min(time.monotonic() + policy.request_timeout_s, ends)
            while (left := until - time.monotonic()) > 0:
                msg = inbox.get(left)
                if msg is not None and _name_of(msg) == name:
                    return float(msg.param_value)
    return None


def _name_of(msg: object) -> str:
    raw = getattr(msg, "param_id", "")
    text = raw.decode("ascii", "replace") if isinstance(raw, bytes) else str(raw)
    return text.rstrip("\x00")


def read_parameter(link: VehicleLink, name: str, policy: RetryPolicy) -> float | None:
    """The vehicle's value of ``name``, or None if it does not answer for it."""
    return _exchange(link, name, partial(param_request_read, name, link.target), policy)


def check_parameters(
    link: VehicleLink, expected: Mapping[str, float], policy: RetryPolicy
) -> tuple[ParameterCheck, ...]:
    """Read every parameter of ``expected`` and compare (nothing is changed).

    The whole read ends by ``policy.deadline_s``, as a transfer does: a parameter the vehicle
    has not answered for by then is reported as not answered (``found`` None).
    """
    ends = time.monotonic() + policy.deadline_s
    return tuple(
        ParameterCheck(
            link.name,
            name,
            value,
            _exchange(link, name, partial(param_request_read, name, link.target), policy, ends),
        )
        for name, value in expected.items()
    )


def set_parameters(
    link: VehicleLink, values: Mapping[str, float], policy: RetryPolicy
) -> tuple[ParameterCheck, ...]:
    """Set every parameter of ``values``, each confirmed by the PARAM_VALUE it returns.

    Raises
    ------
    ParameterError
        For the first parameter the vehicle refused (answered with another value) or did
        not answer for (an unknown name).
    """
    checks = []
    for name, value in values.items():
        found = _exchange(link, name, partial(param_set, name, value, link.target), policy)
        check = ParameterCheck(link.name, name, value, found)
        if not check.ok:
            raise check.error()
        checks.append(check)
    return tuple(checks)
