"""Several vehicles at once: connect, upload, stream, arm and start, one call each.

This is the entry point for the mission builder and the service::

    with Fleet.connect(["udpout:10.0.0.11:14550", ...], RetryPolicy()) as fleet:
        fleet.upload(missions)            # DroneMission per vehicle, in the same order
        with fleet.recorder() as recorder:
            fleet.request_position_streams(rate_hz=10)
            fleet.arm()
            fleet.start()                 # one common MISSION_START: take off to the hold
            ...                           # every vehicle holding (MISSION_CURRENT hold_seq)
            fleet.release(release_seq)    # all leave the hold at once
            ...
            telemetry = recorder.snapshot()

Per-vehicle work runs in a thread per vehicle (joined before each call returns), so the
three uploads proceed concurrently. A call succeeds only if it succeeded on every vehicle;
otherwise :class:`FleetError` carries each vehicle's error and the names of those on which
it worked.
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Mapping, Sequence
from concurrent.futures import ThreadPoolExecutor
from typing import TypeVar

from missions.export.items import DroneMission
from missions.mavlink.commands import (
    ReleaseReport,
    StartReport,
    arm,
    release,
    request_position_stream,
    start_missions,
)
from missions.mavlink.errors import FleetError, MavlinkError
from missions.mavlink.params import ParameterCheck, set_parameters
from missions.mavlink.policy import RetryPolicy
from missions.mavlink.telemetry import TelemetryRecorder
from missions.mavlink.transport import VehicleLink
from missions.mavlink.upload import UploadReport, Verification, upload_and_verify

logger = logging.getLogger(__name__)
T = TypeVar("T")


def on_every_vehicle(
    links: Sequence[VehicleLink], operation: str, work: Callable[[VehicleLink], T]
) -> tuple[T, ...]:
    """Run ``work(link)`` for all links concurrently; results in link order.

    Raises
    ------
    FleetError
        If ``work`` raised a :class:`MavlinkError` on any vehicle (other exceptions
        propagate unchanged: they are bugs, not vehicle behaviour).
    """
    with ThreadPoolExecutor(
        max_workers=max(len(links), 1), thread_name_prefix=f"fleet-{operation}"
    ) as pool:
        futures = [pool.submit(work, link) for link in links]
    failures: dict[str, MavlinkError] = {}
    for link, future in zip(links, futures, strict=True):
        error = future.exception()
        if isinstance(error, MavlinkError):
            failures[link.name] = error
        elif error is not None:
            raise error
    if failures:
        succeeded = tuple(link.name for link in links if link.name not in failures)
        raise FleetError(operation, failures, succeeded)
    return tuple(future.result() for future in futures)


class Fleet:
    """Links to N vehicles (one per connection string), closed together."""

    def __init__(self, links: Sequence[VehicleLink], policy: RetryPolicy) -> None:
        self.links = tuple(links)
        self.policy = policy

    @classmethod
    def connect(
        cls,
        addresses: Sequence[str],
        policy: RetryPolicy | None = None,
        names: Sequence[str] | None = None,
    ) -> Fleet:
        """Open a link per address and wait for every vehicle's heartbeat.

        Raises
        ------
        FleetError
            If a vehicle sent no heartbeat in ``policy.heartbeat_timeout_s`` (all links are
            closed again).
        ConnectionStringError, OSError
            If an address is invalid or cannot be opened.
        """
        policy = policy or RetryPolicy()
        names = list(names) if names is not None else list(addresses)
        if len(names) != len(addresses):
            raise ValueError(f"{len(names)} names for {len(addresses)} addresses")
        links: list[VehicleLink] = []
        try:
            for address, name in zip(addresses, names, strict=True):
                links.append(VehicleLink(address, policy, name=name))
            on_every_vehicle(links, "connect", lambda link: link.wait_heartbeat())
        except BaseException:
            for link in links:
                link.close()
            raise
        return cls(links, policy)

    def close(self) -> None:
        for link in self.links:
            link.close()

    def __enter__(self) -> Fleet:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def upload(
        self,
        missions: Sequence[DroneMission],
        verification: Verification = Verification.ARDUPILOT,
        parameters: Sequence[Mapping[str, float]] | None = None,
    ) -> tuple[UploadReport, ...]:
        """Upload ``missions[i]`` to vehicle ``i``, concurrently, each verified; with
        ``parameters[i]`` (mission i's ``.parm``) read back and compared
        (:attr:`UploadReport.parameter_errors`)."""
        if len(missions) != len(self.links):
            raise ValueError(f"{len(missions)} missions for {len(self.links)} vehicles")
        expected = list(parameters) if parameters is not None else [{}] * len(missions)
        if len(expected) != len(self.links):
            raise ValueError(f"{len(expected)} parameter sets for {len(self.links)} vehicles")
        index = {link: i for i, link in enumerate(self.links)}

        def upload(link: VehicleLink) -> UploadReport:
            i = index[link]
            return upload_and_verify(link, missions[i], self.policy, verification, expected[i])

        return on_every_vehicle(self.links, "upload", upload)

    def set_parameters(
        self, values: Sequence[Mapping[str, float]]
    ) -> tuple[tuple[ParameterCheck, ...], ...]:
        """Set ``values[i]`` (e.g. a mission's ``.parm``) on vehicle ``i``, each confirmed
        by its read-back (:func:`~missions.mavlink.params.set_parameters`)."""
        if len(values) != len(self.links):
            raise ValueError(f"{len(values)} parameter sets for {len(self.links)} vehicles")
        index = {link: i for i, link in enumerate(self.links)}
        return on_every_vehicle(
            self.links, "parameters",
            lambda link: set_parameters(link, values[index[link]], self.policy),
        )  # fmt: skip

    def request_position_streams(self, rate_hz: float) -> None:
        """GLOBAL_POSITION_INT at ``rate_hz`` [Hz] from every vehicle (confirmed arriving)."""
        on_every_vehicle(
            self.links, "stream", lambda link: request_position_stream(link, rate_hz, self.policy)
        )

    def arm(self) -> None:
        on_every_vehicle(self.links, "arm", lambda link: arm(link, self.policy))

    def start(self) -> StartReport:
        """One common MISSION_START to every vehicle (:func:`start_missions`)."""
        return start_missions(self.links, self.policy)

    def release(self, seq: int) -> ReleaseReport:
        """Release every vehicle at once from its hold into item ``seq`` (:func:`release`:
        MISSION_SET_CURRENT sent back to back, never re-sent)."""
        return release(self.links, seq, self.policy)

    def recorder(self) -> TelemetryRecorder:
        """A telemetry recorder on these links (start it, or use ``with``)."""
        return TelemetryRecorder(self.links)


def upload_to_vehicles(
    addresses: Sequence[str],
    missions: Sequence[DroneMission],
    policy: RetryPolicy | None = None,
    verification: Verification = Verification.ARDUPILOT,
    parameters: Sequence[Mapping[str, float]] | None = None,
) -> tuple[UploadReport, ...]:
    """Connect, upload ``missions[i]`` to ``addresses[i]`` with verification and the
    parameter check (:meth:`Fleet.upload`), disconnect."""
    with Fleet.connect(addresses, policy) as fleet:
        return fleet.upload(missions, verification, parameters)
