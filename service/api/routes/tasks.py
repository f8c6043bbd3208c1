"""/v1/tasks: submit, inspect, cancel, download artifacts, upload missions to vehicles."""

from __future__ import annotations

import io
import json
import re
import zipfile
from pathlib import Path

from fastapi import APIRouter, Depends, Query, Request, Response
from fastapi.concurrency import run_in_threadpool
from fastapi.responses import FileResponse, JSONResponse

from flycrane.errors import FieldProblem, InputError
from flycrane.planning.validity import InvalidConfigurationError
from missions.task import TaskSpec, resolve_task
from service.api.routes.view import bundle_view
from service.deps import ServiceState, get_state, require_token
from service.errors import (
    ArtifactNotFoundError,
    TaskNotFoundError,
    TaskNotReadyError,
    UploadNotAllowedError,
)
from service.schemas import (
    ParameterDifference,
    TaskAccepted,
    TaskPage,
    TaskPublic,
    UploadCreate,
    UploadPublic,
    VehicleUpload,
)
from service.storage import TaskRecord, TaskStatus

router = APIRouter(prefix="/v1/tasks", tags=["tasks"])


def _record(state: ServiceState, task_id: str) -> TaskRecord:
    record = state.store.get(task_id)
    if record is None:
        raise TaskNotFoundError(f"no task {task_id!r}")
    return record


def _check_limits(task: TaskSpec, state: ServiceState) -> None:
    """Refuse what the settings do not allow, and scene files over HTTP."""
    problems = []
    limit = state.settings.max_time_budget
    if task.planner.time_budget > limit:
        problems.append(FieldProblem("planner.time_budget", f"at most {limit:g} s here"))
    if not isinstance(task.scene, str):
        for index, shape in enumerate([*task.scene.obstacles, *task.scene.payload.shapes]):
            if getattr(shape, "file", None) is not None:
                problems.append(
                    FieldProblem(
                        f"scene.shape[{index}].file",
                        "mesh files cannot be referenced over HTTP; give vertices and faces",
                    )
                )
    if problems:
        raise InputError(problems)


@router.post(
    "", status_code=202, response_model=TaskAccepted, dependencies=[Depends(require_token)]
)
async def create_task(
    task: TaskSpec, request: Request, state: ServiceState = Depends(get_state)
) -> TaskAccepted | JSONResponse:
    """Validate a task (start and goal included), store it, queue it; 202 with its URL."""
    _check_limits(task, state)
    try:
        await run_in_threadpool(resolve_task, task)
    except InvalidConfigurationError as error:
        state.metrics.submissions.labels("invalid").inc()
        return JSONResponse(
            {
                "detail": [
                    {
                        "loc": ["body", error.what],
                        "msg": str(error.reason),
                        "type": "invalid_configuration",
                    }
                ]
            },
            status_code=422,
        )
    except InputError:
        state.metrics.submissions.labels("invalid").inc()
        raise
    try:
        state.jobs.reserve()
    except Exception:
        state.metrics.submissions.labels("refused").inc()
        raise
    record = state.store.create(task.model_dump(mode="json"))
    state.jobs.submit(record)
    state.metrics.submissions.labels("accepted").inc()
    url = f"{request.base_url}v1/tasks/{record.id}"
    return TaskAccepted(id=record.id, url=url, status=record.status)


@router.get("", response_model=TaskPage)
def list_tasks(
    request: Request,
    status: TaskStatus | None = None,
    offset: int = Query(0, ge=0),
    limit: int = Query(50, ge=1, le=500),
    state: ServiceState = Depends(get_state),
) -> TaskPage:
    """Tasks, newest first, optionally of one status."""
    records, total = state.store.list(status, offset, limit)
    base = str(request.base_url)
    return TaskPage(
        items=[TaskPublic.of(r, base) for r in records], total=total, offset=offset, limit=limit
    )


@router.get("/{task_id}", response_model=TaskPublic)
def get_task(task_id: str, request: Request, state: ServiceState = Depends(get_state)):
    """Status, progress while running, and results when done."""
    return TaskPublic.of(_record(state, task_id), str(request.base_url))


@router.delete("/{task_id}", response_model=TaskPublic, dependencies=[Depends(require_token)])
def cancel_task(task_id: str, request: Request, state: ServiceState = Depends(get_state)):
    """Cancel a queued or running task (a finished one is returned unchanged)."""
    record = _record(state, task_id)
    if not record.status.finished:
        record = state.jobs.cancel(task_id) or record
    return TaskPublic.of(record, str(request.base_url))


def _artifact_path(state: ServiceState, record: TaskRecord, name: str) -> Path:
    files = (record.result or {}).get("artifacts", {})
    if name not in files.values():  # only names the task produced: no path traversal
        raise ArtifactNotFoundError(f"task {record.id} has no artifact {name!r}")
    return state.jobs.task_dir(record.id) / name


@router.get("/{task_id}/artifacts/{name}")
def get_artifact(task_id: str, name: str, state: ServiceState = Depends(get_state)):
    """One artifact file (path.json, tracks.json, droneK.waypoints/.plan/.mission.json,
    mission.mcap, profile.png, summary.json)."""
    record = _record(state, task_id)
    return FileResponse(_artifact_path(state, record, name), filename=name)


@router.get("/{task_id}/bundle.zip")
def get_bundle(task_id: str, state: ServiceState = Depends(get_state)) -> Response:
    """Every artifact of a task in one zip, with view.html, the viewer page that opens offline."""
    record = _record(state, task_id)
    files = (record.result or {}).get("artifacts", {})
    if not files:
        raise TaskNotReadyError(f"task {task_id} has no artifacts (status {record.status})")
    buffer = io.BytesIO()
    with zipfile.ZipFile(buffer, "w", zipfile.ZIP_DEFLATED) as archive:
        for name in sorted(set(files.values())):
            archive.write(_artifact_path(state, record, name), arcname=name)
        if record.status is TaskStatus.DONE:  # the viewer, standalone (docs/viewer.md)
            archive.writestr("view.html", bundle_view(state, record))
    return Response(
        buffer.getvalue(),
        media_type="application/zip",
        headers={"Content-Disposition": f'attachment; filename="{task_id}.zip"'},
    )


def _allowed(address: str, patterns: tuple[str, ...]) -> bool:
    return any(re.fullmatch(pattern, address) for pattern in patterns)


@router.post(
    "/{task_id}/upload",
    response_model=UploadPublic,
    dependencies=[Depends(require_token)],
    responses={
        409: {"model": UploadPublic, "description": "uploaded; a vehicle's parameters differ"},
        502: {"model": UploadPublic, "description": "a vehicle failed"},
    },
)
async def upload_task(
    task_id: str, body: UploadCreate, state: ServiceState = Depends(get_state)
) -> UploadPublic | JSONResponse:
    """Upload the three missions (drone k to ``vehicles[k-1]``), verify by read-back, read
    the parameters of ``drone{k}.parm`` back from each vehicle, record the outcome per
    vehicle. 502 if any vehicle failed (the others keep their mission); 409 if every mission
    is on board but a vehicle's parameters differ from the plan's (the mission's timing
    holds only with them: set them, e.g. by loading the ``.parm`` in the ground station)."""
    from missions.formats import mission_from_json
    from missions.mavlink import FleetError, RetryPolicy, upload_to_vehicles
    from missions.parameter_file import read_parameter_file

    record = _record(state, task_id)
    refused = [v for v in body.vehicles if not _allowed(v, state.settings.upload_allow)]
    if refused:
        raise UploadNotAllowedError(
            f"vehicle address {refused[0]!r} is not allowed (FLYCRANE_UPLOAD_ALLOW)"
        )
    if record.status is not TaskStatus.DONE:
        raise TaskNotReadyError(f"task {task_id} is {record.status}, not done")
    missions = [
        mission_from_json(
            json.loads(
                _artifact_path(state, record, f"drone{k}.mission.json").read_text(encoding="utf-8")
            )
        )
        for k in (1, 2, 3)
    ]
    parameters = [read_parameter_file(_artifact_path(state, record, f"drone{k}.parm"))
                  for k in (1, 2, 3)]  # fmt: skip
    policy = RetryPolicy(deadline_s=state.settings.upload_timeout)
    failures: dict[str, str] = {}
    differences: dict[str, list[ParameterDifference]] = {}
    try:
        reports = await run_in_threadpool(
            upload_to_vehicles, list(body.vehicles), missions, policy, parameters=parameters
        )
        differences = {
            report.vehicle: [ParameterDifference(name=e.name, expected=e.expected, found=e.found)
                             for e in report.parameter_errors]
            for report in reports
        }  # fmt: skip
    except FleetError as error:
        failures = {name: str(problem) for name, problem in error.failures.items()}
    except Exception as error:
        failures = {v: f"{type(error).__name__}: {error}" for v in body.vehicles}
    vehicles = []
    for k, vehicle in enumerate(body.vehicles):
        differ = differences.get(vehicle, [])
        detail = failures.get(vehicle, "uploaded and verified")
        if differ:
            detail += "; parameters differ from the plan's: " + ", ".join(
                f"{d.name} should be {d.expected:g}, the vehicle has "
                + ("none" if d.found is None else f"{d.found:g}")
                for d in differ
            )
        ok = vehicle not in failures and not differ
        vehicles.append(VehicleUpload(drone=k + 1, vehicle=vehicle, ok=ok, detail=detail,
                                      parameter_differences=differ))  # fmt: skip
    outcome = UploadPublic(ok=all(v.ok for v in vehicles), vehicles=vehicles)
    state.store.add_upload(task_id, outcome.model_dump())
    if failures:
        return JSONResponse(outcome.model_dump(), status_code=502)
    if not outcome.ok:
        return JSONResponse(outcome.model_dump(), status_code=409)
    return outcome
