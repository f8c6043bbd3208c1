"""Before the release: does each vehicle position itself the way the plan assumes?

The plan's clearance follows from a position-error model (:mod:`missions.position_error`),
and the model holds only with the positioning it names: its height source and its GNSS fix.
What a vehicle is set to use is known on the ground: :func:`settings_reasons` names each
drone whose height source (EK3_SRC1_POSZ) is not the model's, so that a team the model does
not hold for need not take off to be refused. With the three drones holding at the start,
:func:`check_readiness` reads what each reports and refuses the release, naming the drone
and the reason, when

- its height source is not the model's;
- its GNSS fix (GPS_RAW_INT) is worse than the model's;
- its estimate lacks a flag a position-holding flight needs (EKF_STATUS_REPORT);
- its estimated altitude and its GNSS altitude differ by more than the model's common
  vertical bound (a barometer that drifted, as SITL's uncalibrated ones do by 4-5 % of the
  height: the plan's clearance would be spent before the flight starts);
- its estimate is farther from its hold, or the drones' distances from the plan's, than the
  model's bounds.
"""

from __future__ import annotations

import math
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace
from itertools import combinations
from typing import Any

import numpy as np
from numpy.typing import NDArray

from missions.autopilots.ardupilot import HEIGHT_SOURCE_PARAMETER, HEIGHT_SOURCES
from missions.execution.team import EKF_NEEDED
from missions.geodesy import DEGREE_UNIT, enu_from_geodetic
from missions.mavlink.commands import set_message_interval
from missions.mavlink.params import read_parameter
from missions.mavlink.policy import RetryPolicy
from missions.mavlink.transport import VehicleLink
from missions.options import GeodeticOrigin
from missions.position_error import PositionErrorModel

#: What the check reads from each vehicle, and how often it asks for it [s].
READ = ("GLOBAL_POSITION_INT", "GPS_RAW_INT", "EKF_STATUS_REPORT")
READ_INTERVAL_S = 0.2


@dataclass(frozen=True)
class Readiness:
    """Whether the release may go out, and every reason it may not (one per finding)."""

    reasons: tuple[str, ...] = ()
    #: per drone: estimated altitude minus GNSS altitude [m], distance to its hold [m]
    altitude_disagreement: tuple[float, ...] = ()
    hold_error: tuple[float, ...] = ()
    formation_error: float = 0.0  #: worst pair's distance error against the plan [m]

    @property
    def ready(self) -> bool:
        return not self.reasons


@dataclass
class _Latest:
    messages: dict[str, Any] = field(default_factory=dict)

    def __call__(self, msg: Any) -> None:
        self.messages[msg.get_type()] = msg


def settings_reasons(
    links: Sequence[VehicleLink], model: PositionErrorModel, policy: RetryPolicy
) -> tuple[str, ...]:
    """One reason per drone whose height source is not the one ``model`` assumes.

    Raises
    ------
    MavlinkError
        A parameter read went unanswered.
    """
    wanted = HEIGHT_SOURCES.get(model.height_source)
    if wanted is None:
        return ()
    reasons = []
    for k, link in enumerate(links):
        source = read_parameter(link, HEIGHT_SOURCE_PARAMETER, policy)
        if source is None or round(source) != wanted:
            reasons.append(
                f"drone {k + 1} ({link.name}): {HEIGHT_SOURCE_PARAMETER} is {source}, the "
                f"{model.height_source} height the position-error model assumes is {wanted}"
            )
    return tuple(reasons)


def check_readiness(
    links: Sequence[VehicleLink],
    model: PositionErrorModel,
    holds: NDArray[np.float64],
    origin: GeodeticOrigin,
    home_height: float,
    policy: RetryPolicy,
    timeout: float = 10.0,
) -> Readiness:
    """Check the three vehicles at their holds (module docstring). ``holds`` (3, 3):
    where each drone holds in the task's ENU frame; altitudes count from homes
    ``home_height`` above the ground, as the missions' do.

    Raises
    ------
    MavlinkError
        A parameter read went unanswered.
    """
    latest = [_Latest() for _ in links]
    for link, sink in zip(links, latest, strict=True):
        link.add_listener(READ, sink)
        for name in READ:
            set_message_interval(link, name, READ_INTERVAL_S, policy)
    try:
        deadline = time.monotonic() + timeout
        while any(set(READ) - set(s.messages) for s in latest) and time.monotonic() < deadline:
            time.sleep(0.01)
        settings = settings_reasons(links, model, policy)
    finally:
        for link, sink in zip(links, latest, strict=True):
            link.remove_listener(sink)
    names = [f"drone {k + 1} ({link.name})" for k, link in enumerate(links)]
    reports = [sink.messages for sink in latest]
    checked = judge_readiness(names, reports, model, holds, origin, home_height)
    return replace(checked, reasons=settings + checked.reasons)


def judge_readiness(
    names: Sequence[str],
    reports: Sequence[Mapping[str, Any]],
    model: PositionErrorModel,
    holds: NDArray[np.float64],
    origin: GeodeticOrigin,
    home_height: float,
) -> Readiness:
    """Judge what each drone reported (its latest message of each type in :data:`READ`,
    by type name) against ``model`` at ``holds`` (:func:`check_readiness`)."""
    reasons: list[str] = []
    disagreement, hold_error, positions = [], [], []
    for k, (name, messages) in enumerate(zip(names, reports, strict=True)):
        missing = set(READ) - set(messages)
        if missing:
            reasons.append(f"{name}: no {', '.join(sorted(missing))}")
            disagreement.append(math.nan)
            hold_error.append(math.nan)
            continue
        estimate, gps = messages["GLOBAL_POSITION_INT"], messages["GPS_RAW_INT"]
        flags = messages["EKF_STATUS_REPORT"].flags
        if gps.fix_type < model.min_fix_type:
            reasons.append(f"{name}: GNSS fix type {gps.fix_type} < {model.min_fix_type}")
        if flags & EKF_NEEDED != EKF_NEEDED:
            reasons.append(f"{name}: EKF flags {flags:#x} lack {EKF_NEEDED & ~flags:#x}")
        difference = (estimate.alt - gps.alt) / 1000.0
        disagreement.append(difference)
        if abs(difference) > model.common_vertical:
            reasons.append(
                f"{name}: estimated altitude {difference:+.3f} m from the GNSS altitude, "
                f"beyond the model's {model.common_vertical:.3f} m"
            )
        position = enu_from_geodetic(
            estimate.lat * DEGREE_UNIT,
            estimate.lon * DEGREE_UNIT,
            estimate.relative_alt / 1000.0 + home_height + origin.altitude,
            origin,
        )
        positions.append(position)
        error = position - holds[k]
        hold_error.append(float(np.linalg.norm(error)))
        if (
            np.hypot(error[0], error[1]) > model.common_horizontal + model.relative_horizontal
            or abs(error[2]) > model.common_vertical + model.relative_vertical
        ):
            reasons.append(f"{name}: {np.round(error, 3).tolist()} m from its hold (ENU)")
    formation = 0.0
    if len(positions) == 3:
        bound = float(np.hypot(model.relative_horizontal, model.relative_vertical))
        formation = max(
            float(abs(np.linalg.norm(p - q) - np.linalg.norm(holds[i] - holds[j])))
            for (i, p), (j, q) in combinations(enumerate(positions), 2)
        )
        if formation > bound:
            reasons.append(
                f"the formation is {formation:.3f} m off the plan's, beyond {bound:.3f} m"
            )
    return Readiness(tuple(reasons), tuple(disagreement), tuple(hold_error), float(formation))
