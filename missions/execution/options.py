"""How an execution plays the plan: its rate, start, lead and the rules it judges by."""

from __future__ import annotations

from dataclasses import dataclass, field

from missions.execution.group_clock import RatePolicy
from missions.execution.team import MonitorLimits

#: The most a target may be ahead of its vehicle's present [s]: beyond, a lead would hide
#: a slow vehicle rather than make up its controller's lag.
MAX_LEAD_S = 0.3
#: The rates an executor may tick at [Hz].
RATE_RANGE_HZ = (10.0, 50.0)
#: The longest start delay [s]: from the start command to plan time 0.
MAX_START_DELAY_S = 60.0


@dataclass(frozen=True)
class ExecutionOptions:
    """How the plan is played (times in seconds of common time)."""

    rate_hz: float = 20.0  #: ticks per second of vehicle time (10-50)
    #: from the start command to plan time 0; None: the executor's own
    #: (:attr:`~.executor.Executor.default_start_delay`)
    start_delay: float | None = None
    max_extrapolation: float = 0.1  #: of a vehicle's clock past its last message
    #: targets are for this much ahead of a vehicle's present [s of common time],
    #: (horizontal, vertical): what its controller lags them by on top of their way to it;
    #: None: the executor's own :attr:`~.executor.Executor.lead`
    lead: tuple[float, float] | None = None
    policy: RatePolicy = field(default_factory=RatePolicy)
    limits: MonitorLimits = field(default_factory=MonitorLimits)

    def __post_init__(self) -> None:
        low, high = RATE_RANGE_HZ
        if not low <= self.rate_hz <= high:
            raise ValueError(f"rate_hz: {self.rate_hz} is outside {low:g}-{high:g} Hz")
        if self.lead is not None and not all(0.0 <= x <= MAX_LEAD_S for x in self.lead):
            raise ValueError(f"lead: {self.lead} is outside 0-{MAX_LEAD_S} s")
        if self.start_delay is not None and not 0.0 <= self.start_delay <= MAX_START_DELAY_S:
            raise ValueError(
                f"start_delay: {self.start_delay} is outside 0-{MAX_START_DELAY_S:g} s"
            )
