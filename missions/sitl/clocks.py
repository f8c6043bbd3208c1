"""The simulators' clocks brought together before the release [SITL].

Each simulator's clock (its SYSTEM_TIME: one epoch for the three, plus its own simulated
time) advances at its own pace from its own process start. Three simulators on a 2-core
host end their boot tens of milliseconds apart, more after a boot faster than the flight
(BENCHMARKS.md "The recorded estimates, a faster boot and the simulators' clocks"), where
real vehicles share GNSS time to the microsecond. The ground reads a drone whose clock
lags as silent by that much. So before the release the harness measures how far each
clock leads the latest one, at the flight's pace, and runs each that leads slower until
the others have caught up.
"""

from __future__ import annotations

import logging
import statistics
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

from missions.mavlink.params import set_parameters
from missions.mavlink.policy import RetryPolicy
from missions.mavlink.transport import VehicleLink

logger = logging.getLogger(__name__)

#: Leads below this are left alone [s of simulated time]: the measure's own scatter.
LEAD_TOLERANCE_S = 0.004
#: Wall time over which each lead is measured [s].
MEASURE_WINDOW_S = 0.5
#: Measures and hold-backs at most.
ROUNDS = 3
#: A lead is taken back over at least this much wall time [s], at a pace that much less
#: than the flight's: an error in the hold-back's duration then costs a fraction of it.
HOLD_BACK_S = 0.25


def clock_leads(links: Sequence[VehicleLink], speedup: float) -> dict[str, float]:
    """How far each vehicle's clock leads the latest one's [s of simulated time]: the median
    over :data:`MEASURE_WINDOW_S` of its GLOBAL_POSITION_INT's time_boot_ms minus
    ``speedup`` times the ground's receipt time."""
    samples: dict[str, list[float]] = {link.name: [] for link in links}

    def listener(name: str) -> Callable[[Any], None]:
        def on(msg: Any) -> None:
            samples[name].append(msg.time_boot_ms / 1000.0 - speedup * time.monotonic())

        return on

    listeners = [(link, listener(link.name)) for link in links]
    for link, on in listeners:
        link.add_listener(("GLOBAL_POSITION_INT",), on)
    try:
        time.sleep(MEASURE_WINDOW_S)
    finally:
        for link, on in listeners:
            link.remove_listener(on)
    ahead = {name: statistics.median(s) for name, s in samples.items() if s}
    latest = min(ahead.values(), default=0.0)
    return {name: a - latest for name, a in ahead.items()}


@dataclass(frozen=True)
class ClockAlignment:
    """What :func:`align_clocks` found and left."""

    before: dict[str, float]  #: each clock's lead at first [s of simulated time]
    after: dict[str, float]  #: and at last
    #: ground monotonic time from which every simulator kept its pace: a reading of a
    #: vehicle's clock from before, carried forward at the pace, misjudges its present
    settled_at: float


def align_clocks(
    links: Sequence[VehicleLink], speedup: float, policy: RetryPolicy
) -> ClockAlignment:
    """Bring the vehicles' clocks within :data:`LEAD_TOLERANCE_S` of each other, each
    simulator at ``speedup`` (SIM_SPEEDUP) before and after. Up to :data:`ROUNDS` times: a
    host that oversleeps a hold-back leaves a lead of its own."""
    settled_at = time.monotonic()
    before = leads = clock_leads(links, speedup)
    for _ in range(ROUNDS):
        ahead = [link for link in links if leads.get(link.name, 0.0) > LEAD_TOLERANCE_S]
        if not ahead:
            break
        for link in ahead:
            _hold_back(link, leads[link.name], speedup, policy)
        settled_at = time.monotonic()
        leads = clock_leads(links, speedup)
    # a simulator starved of the host's cores runs below any pace it is given
    level = logging.WARNING if max(leads.values(), default=0.0) > LEAD_TOLERANCE_S else logging.INFO
    logger.log(
        level,
        "simulators' clock leads before the release [ms]: %s -> %s",
        {n: round(1000 * v) for n, v in before.items()},
        {n: round(1000 * v) for n, v in leads.items()},
    )
    return ClockAlignment(before, leads, settled_at)


def _hold_back(link: VehicleLink, lead: float, speedup: float, policy: RetryPolicy) -> None:
    """Run ``link``'s simulator slower for :data:`HOLD_BACK_S` of wall time (longer for a
    lead beyond half of it), so that it falls ``lead`` behind where it would have been.
    Each pace takes effect about half a round trip after it was sent, the first's confirmed
    a whole round trip after: the wait between them is the hold-back less that round trip."""
    duration = max(HOLD_BACK_S, 2.0 * lead / speedup)
    sent = time.monotonic()
    set_parameters(link, {"SIM_SPEEDUP": speedup - lead / duration}, policy)
    time.sleep(max(0.0, duration - (time.monotonic() - sent)))
    set_parameters(link, {"SIM_SPEEDUP": speedup}, policy)
