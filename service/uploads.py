"""Uploading a task's three missions: which addresses are allowed, and one outcome per vehicle.

Allow-list. An address is parsed (:func:`missions.mavlink.transport.parse_connection`), then
checked on what was parsed, and what was checked is what is connected to:

- a network address must be an IP address (``ipaddress``: ASCII decimal octets, each at most
  255) inside one of ``upload_networks``. Host names are refused, never resolved: a resolver
  (or a hosts file) could send "localhost" anywhere;
- a serial device must match one of ``upload_devices`` whole (USB adapters and flight
  controllers by default; consoles such as /dev/tty0 or /dev/ttyS0 do not).

Each vehicle is connected to, uploaded to and verified on its own (three threads at once),
so one vehicle's failure is reported for that vehicle only and the others keep their
mission; then the parameters the plan assumes (its ``.parm``) are read back from it and
every difference is reported. The three addresses must reach three different vehicles.
"""

from __future__ import annotations

import ipaddress
import re
from collections.abc import Mapping, Sequence
from concurrent.futures import ThreadPoolExecutor

from flycrane.errors import FieldProblem, InputError
from missions.export.items import DroneMission
from missions.mavlink.errors import MavlinkError
from missions.mavlink.policy import RetryPolicy
from missions.mavlink.transport import ConnectionSpec, VehicleLink, parse_connection
from missions.mavlink.upload import Verification, upload_and_verify
from service.artifacts import stored_missions
from service.errors import UploadNotAllowedError
from service.jobs import JobManager
from service.schemas import ParameterDifference, UploadPublic, VehicleUpload
from service.settings import Settings
from service.storage import TaskRecord, TaskStore


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


def _upload_one(
    drone: int,
    address: str,
    mission: DroneMission,
    parameters: Mapping[str, float],
    policy: RetryPolicy,
) -> VehicleUpload:
    try:
        with VehicleLink(address, policy, name=f"drone {drone} ({address})") as link:
            link.wait_heartbeat()
            report = upload_and_verify(link, mission, policy, Verification.ARDUPILOT, parameters)
    except (MavlinkError, OSError) as error:
        return VehicleUpload(
            drone=drone, vehicle=address, ok=False, detail=f"{type(error).__name__}: {error}"
        )
    detail = f"uploaded and verified ({report.item_count} items, {report.duration_s:.1f} s)"
    errors = report.parameter_errors
    if errors:
        detail += "; parameters differ from the plan's: " + ", ".join(
            f"{e.name} should be {e.expected:g}, the vehicle has "
            + ("none" if e.found is None else f"{e.found:g}")
            for e in errors
        )
    differences = [ParameterDifference(name=e.name, expected=e.expected, found=e.found)
                   for e in errors]  # fmt: skip
    return VehicleUpload(drone=drone, vehicle=address, ok=not errors, detail=detail,
                         parameter_differences=differences)  # fmt: skip


def upload_missions(
    addresses: Sequence[str],
    missions: Sequence[DroneMission],
    parameters: Sequence[Mapping[str, float]],
    policy: RetryPolicy,
) -> list[VehicleUpload]:
    """Upload ``missions[k]`` to ``addresses[k]`` (drone k + 1) and check ``parameters[k]``
    on it, all at once; one outcome per vehicle."""
    with ThreadPoolExecutor(max_workers=len(addresses), thread_name_prefix="upload") as pool:
        futures = [
            pool.submit(_upload_one, k + 1, address, mission, expected, policy)
            for k, (address, mission, expected) in enumerate(
                zip(addresses, missions, parameters, strict=True)
            )
        ]
    return [future.result() for future in futures]


def upload_task(
    record: TaskRecord,
    addresses: Sequence[str],
    settings: Settings,
    jobs: JobManager,
    store: TaskStore,
) -> UploadPublic:
    """Upload a done task's missions to the vehicles at ``addresses`` (checked), read its
    parameters back from each, and store the outcome.

    Raises
    ------
    InputError, UploadNotAllowedError
        An address is malformed, repeated or not allowed (:func:`allowed_vehicles`).
    TaskNotReadyError, ArtifactNotFoundError, ArtifactUnreadableError
        The task is not done, or its mission files are unusable.
    """
    vehicles = allowed_vehicles(addresses, settings)
    missions, parameters = stored_missions(jobs, record)
    policy = RetryPolicy(deadline_s=settings.upload_timeout)
    uploads = upload_missions(vehicles, missions, parameters, policy)
    outcome = UploadPublic(ok=all(v.ok for v in uploads), vehicles=uploads)
    store.add_upload(record.id, outcome.model_dump())
    return outcome
