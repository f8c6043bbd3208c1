"""Uploading a task's three missions: which addresses are allowed, and one outcome per vehicle.

Allow-list. An address is parsed (:func:`missions.mavlink.transport.parse_connection`), then
checked on what was parsed, and what was checked is what is connected to:

- a network address must be an IP address (``ipaddress``: ASCII decimal octets, each at most
  255) inside one of ``upload_networks``. Host names are refused, never resolved: a resolver
  (or a hosts file) could send "localhost" anywhere;
- a serial device must match one of ``upload_devices`` whole (USB adapters and flight
  controllers by default; consoles such as /dev/tty0 or /dev/ttyS0 do not).

The vehicles are connected to first, all at once; their heartbeats say which system each
address reaches, and addresses that reach the same system id are refused (422) before
anything is sent: three addresses must reach three different vehicles. Then each vehicle is
uploaded to and verified on its own (a thread each), so one vehicle's failure is reported
for that vehicle only and the others keep their mission; then the parameters the plan
assumes (its ``.parm``) are read back from it and every difference is reported (a value
that is not a number, NaN or infinity, included: ``found`` null, ``found_text`` says it).

``FLYCRANE_UPLOAD_TIMEOUT`` bounds the whole upload of every vehicle: connection, mission
transfer, read-back and parameter reads (:meth:`~missions.mavlink.policy.RetryPolicy.until`).
At most ``FLYCRANE_MAX_CONCURRENT_UPLOADS`` uploads run at once, on threads of their own
(:class:`UploadRunner`), never on the API's request threads; more are refused with 503.
"""

from __future__ import annotations

import ipaddress
import re
import time
from collections.abc import Callable, Mapping, Sequence
from concurrent.futures import Future, ThreadPoolExecutor
from typing import TypeVar

from flycrane.errors import FieldProblem, InputError
from missions.export.items import DroneMission
from missions.mavlink.errors import MavlinkError, MavlinkTimeoutError
from missions.mavlink.policy import RetryPolicy
from missions.mavlink.transport import ConnectionSpec, VehicleLink, parse_connection
from missions.mavlink.upload import Verification, upload_and_verify
from service.artifacts import stored_missions
from service.errors import SameVehicleError, TaskNotFoundError, UploadNotAllowedError
from service.jobs import JobManager
from service.limits import Slots
from service.schemas import ParameterDifference, UploadPublic, VehicleUpload
from service.settings import Settings
from service.storage import TaskStore

T = TypeVar("T")


def _canonical(spec: ConnectionSpec) -> str:
    """The address as it is connected to, from its parsed parts."""
    if spec.kind == "serial":
        return f"{spec.device},{spec.baud}"
    return f"{spec.kind}:{spec.host}:{spec.port}"


def refusal(spec: ConnectionSpec, settings: Settings) -> str | None:
    """Why ``spec`` is not allowed by the settings, or None if it is."""
    if spec.kind == "serial":
        if any(re.fullmatch(p, spec.device, re.ASCII) for p in settings.upload_devices):
            return None
        return f"serial device {spec.device!r} is not allowed (FLYCRANE_UPLOAD_DEVICES)"
    try:
        address = ipaddress.ip_address(spec.host)
    except ValueError:
        return f"{spec.host!r} is not an IP address (host names are not resolved here)"
    if any(address in network for network in settings.upload_networks):
        return None
    return f"{address} is outside the allowed networks (FLYCRANE_UPLOAD_NETWORKS)"


def allowed_vehicles(addresses: Sequence[str], settings: Settings) -> list[str]:
    """The canonical addresses of the vehicles, checked.

    Raises
    ------
    InputError
        An address does not parse, or two reach the same vehicle (422, ``vehicles[k]``).
    UploadNotAllowedError
        An address is outside the allow-list (403).
    """
    specs: list[ConnectionSpec] = []
    problems = []
    for k, address in enumerate(addresses):
        try:
            specs.append(parse_connection(address))
        except InputError as error:
            problems += [FieldProblem(f"vehicles[{k}]", p.reason) for p in error.problems]
    if problems:
        raise InputError(problems)
    for address, spec in zip(addresses, specs, strict=True):
        reason = refusal(spec, settings)
        if reason is not None:
            raise UploadNotAllowedError(f"vehicle address {address!r}: {reason}")
    seen: dict[tuple[str, int] | str, int] = {}
    for k, spec in enumerate(specs):
        key = spec.device if spec.kind == "serial" else (spec.host, spec.port)
        if key in seen:
            problems.append(
                FieldProblem(
                    f"vehicles[{k}]",
                    f"the same vehicle as vehicles[{seen[key]}]: each drone needs its own",
                )
            )
        seen.setdefault(key, k)
    if problems:
        raise InputError(problems)
    return [_canonical(spec) for spec in specs]


def _failed(drone: int, address: str, error: Exception) -> VehicleUpload:
    return VehicleUpload(
        drone=drone, vehicle=address, ok=False, detail=f"{type(error).__name__}: {error}"
    )


def _connect(
    drone: int, address: str, policy: RetryPolicy, ends: float
) -> VehicleLink | VehicleUpload:
    """A link to the vehicle at ``address`` once its heartbeat came, or why not."""
    name = f"drone {drone} ({address})"
    try:
        link = VehicleLink(address, policy, name=name)
    except (MavlinkError, OSError) as error:  # no such device, port in use, ...
        detail = f"{name}: cannot open the link: {type(error).__name__}: {error}"
        return VehicleUpload(drone=drone, vehicle=address, ok=False, detail=detail)
    try:
        link.wait_heartbeat(min(policy.heartbeat_timeout_s, max(ends - time.monotonic(), 0.0)))
    except MavlinkError as error:
        link.close()
        return _failed(drone, address, error)
    return link


def require_distinct(addresses: Sequence[str], links: Mapping[int, VehicleLink]) -> None:
    """Refuse addresses (by index) that reach a system id an earlier one reaches.

    Raises
    ------
    SameVehicleError
        Naming each such address, the first one that reaches its vehicle and the system id.
    """
    first: dict[int, int] = {}
    repeats = []
    for k in sorted(links):
        system = links[k].info.system_id
        if system in first:
            repeats.append((k, first[system], system))
        else:
            first[system] = k
    if repeats:
        raise SameVehicleError(addresses, repeats)


def _upload_one(
    drone: int,
    link: VehicleLink,
    mission: DroneMission,
    parameters: Mapping[str, float],
    policy: RetryPolicy,
    ends: float,
) -> VehicleUpload:
    address = link.address
    try:
        report = upload_and_verify(
            link, mission, policy, Verification.ARDUPILOT, parameters, ends=ends
        )
    except MavlinkTimeoutError as error:
        if time.monotonic() < ends:
            return _failed(drone, address, error)
        return VehicleUpload(
            drone=drone,
            vehicle=address,
            ok=False,
            detail=f"{link.name}: the upload did not end within FLYCRANE_UPLOAD_TIMEOUT "
            f"({policy.deadline_s:g} s); it was waiting for {error.stage}",
        )
    except (MavlinkError, OSError) as error:
        return _failed(drone, address, error)
    detail = f"uploaded and verified ({report.item_count} items, {report.duration_s:.1f} s)"
    errors = report.parameter_errors
    if errors:
        detail += "; parameters differ from the plan's: " + ", ".join(
            f"{e.name} should be {e.expected:g}, the vehicle has "
            + ("none" if e.found is None else f"{e.found:g}")
            for e in errors
        )
    differences = [ParameterDifference.of(e.name, e.expected, e.found) for e in errors]
    return VehicleUpload(
        drone=drone, vehicle=address, ok=not errors, detail=detail,
        parameter_differences=differences,
    )  # fmt: skip


def upload_missions(
    addresses: Sequence[str],
    missions: Sequence[DroneMission],
    parameters: Sequence[Mapping[str, float]],
    policy: RetryPolicy,
) -> list[VehicleUpload]:
    """Upload ``missions[k]`` to ``addresses[k]`` (drone k + 1) and check ``parameters[k]``
    on it, all at once, everything within ``policy.deadline_s``; one outcome per vehicle.

    Raises
    ------
    SameVehicleError
        Two addresses reach the same vehicle (nothing was sent to it).
    """
    ends = time.monotonic() + policy.deadline_s
    count = len(addresses)
    with ThreadPoolExecutor(max_workers=count, thread_name_prefix="upload") as pool:
        connected = list(
            pool.map(lambda k: _connect(k + 1, addresses[k], policy, ends), range(count))
        )
        links = {k: c for k, c in enumerate(connected) if isinstance(c, VehicleLink)}
        try:
            require_distinct(addresses, links)
            futures = {
                k: pool.submit(_upload_one, k + 1, link, missions[k], parameters[k], policy, ends)
                for k, link in links.items()
            }
            outcomes = [
                outcome if isinstance(outcome, VehicleUpload) else futures[k].result()
                for k, outcome in enumerate(connected)
            ]
        finally:
            for link in links.values():
                link.close()
    return outcomes


def upload_task(
    task_id: str,
    addresses: Sequence[str],
    settings: Settings,
    jobs: JobManager,
    store: TaskStore,
) -> UploadPublic:
    """Upload a done task's missions to the vehicles at ``addresses`` (checked), read its
    parameters back from each, and store the outcome.

    Raises
    ------
    TaskNotFoundError
        No such task.
    InputError, UploadNotAllowedError
        An address is malformed, repeated or not allowed (:func:`allowed_vehicles`).
    SameVehicleError
        Two addresses reach the same vehicle (:func:`require_distinct`).
    TaskNotReadyError, ArtifactNotFoundError, ArtifactUnreadableError
        The task is not done, or its mission files are unusable.
    """
    record = store.get(task_id)
    if record is None:
        raise TaskNotFoundError(f"no task {task_id!r}")
    vehicles = allowed_vehicles(addresses, settings)
    missions, parameters = stored_missions(jobs, record)
    policy = RetryPolicy(deadline_s=settings.upload_timeout)
    uploads = upload_missions(vehicles, missions, parameters, policy)
    outcome = UploadPublic(ok=all(v.ok for v in uploads), vehicles=uploads)
    store.add_upload(record.id, outcome.model_dump(mode="json"))
    return outcome


class UploadRunner:
    """Runs uploads on threads of their own, at most ``limit`` at once.

    An upload waits for vehicles for up to ``FLYCRANE_UPLOAD_TIMEOUT``: on the API's request
    threads, sixty of them took every thread and /healthz waited 3.7 s. Beyond the limit an
    upload is refused at once with 503 and Retry-After (``retry_after`` [s]).
    """

    def __init__(self, limit: int, retry_after: float) -> None:
        self.limit = limit
        self._slots = Slots(limit, "uploads", retry_after)
        self._pool = ThreadPoolExecutor(max_workers=limit, thread_name_prefix="upload-task")

    def submit(self, work: Callable[[], T]) -> Future[T]:
        """Run ``work()`` on a free slot.

        Raises
        ------
        ServiceBusyError
            If ``limit`` uploads are running.
        """
        self._slots.take()
        try:
            future = self._pool.submit(work)
        except BaseException:
            self._slots.give_back()
            raise
        future.add_done_callback(lambda _: self._slots.give_back())
        return future

    def stop(self) -> None:
        """At shutdown: uploads not started are dropped, running ones end by their deadline."""
        self._pool.shutdown(wait=False, cancel_futures=True)
