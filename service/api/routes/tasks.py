"""/v1/tasks: submit, inspect, cancel, download artifacts, upload missions to vehicles.

Handlers are plain functions: FastAPI runs them in its thread pool, so a slow or locked
database holds one thread, never the event loop (a locked SQLite answers 503 after
``database_busy_timeout``).
"""

from __future__ import annotations

import io
import json
import zipfile
from pathlib import Path

from fastapi import APIRouter, Depends, Query
from fastapi.responses import FileResponse, JSONResponse, Response

from flycrane.errors import FieldProblem, InputError
from missions.task.spec import TaskSpec, require_served_task, resolve_task
from service.api.routes.view import bundle_view
from service.deps import ServiceState, base_url, get_state, require_reader, require_token
from service.errors import (
    ArtifactNotFoundError,
    ArtifactUnreadableError,
    TaskNotFoundError,
    TaskNotReadyError,
    error_responses,
)
from service.schemas import TaskAccepted, TaskPage, TaskPublic, UploadCreate, UploadPublic
from service.storage import MAX_OFFSET, TaskRecord, TaskStatus
from service.uploads import allowed_vehicles, upload_missions

router = APIRouter(prefix="/v1/tasks", tags=["tasks"])

_FILE = {"type": "string", "format": "binary"}
#: Media types of the artifacts, by extension.
MEDIA_TYPES = {
    ".json": "application/json",
    ".plan": "application/json",
    ".waypoints": "text/plain",
    ".mcap": "application/octet-stream",
    ".png": "image/png",
}
#: JSON artifacts are objects; the others are files (text or bytes).
_ARTIFACT_CONTENT = {
    media: {"schema": {"type": "object"} if media == "application/json" else _FILE}
    for media in sorted(set(MEDIA_TYPES.values()))
}


def _record(state: ServiceState, task_id: str) -> TaskRecord:
    record = state.store.get(task_id)
    if record is None:
        raise TaskNotFoundError(f"no task {task_id!r}")
    return record


def _check_limits(task: TaskSpec, state: ServiceState) -> None:
    """Refuse what the settings do not allow, and files named over HTTP."""
    problems = []
    limit = state.settings.max_time_budget
    if task.planner.time_budget > limit:
        problems.append(FieldProblem("planner.time_budget", f"at most {limit:g} s here"))
    if problems:
        raise InputError(problems)
    require_served_task(task)


@router.post(
    "",
    status_code=202,
    response_model=TaskAccepted,
    dependencies=[Depends(require_token)],
    responses=error_responses(401, 413, 503),
)
def create_task(
    task: TaskSpec, state: ServiceState = Depends(get_state), base: str = Depends(base_url)
) -> TaskAccepted:
    """Validate a task (start and goal included), store it, queue it; 202 with its URL."""
    try:
        _check_limits(task, state)
        resolve_task(task)
    except Exception:
        state.metrics.submissions.labels("invalid").inc()
        raise
    try:
        with state.jobs.slot():
            record = state.store.create(task.model_dump(mode="json"))
            state.jobs.submit(record)
    except Exception:
        state.metrics.submissions.labels("refused").inc()
        raise
    state.metrics.submissions.labels("accepted").inc()
    return TaskAccepted(id=record.id, url=f"{base}v1/tasks/{record.id}", status=record.status)


@router.get(
    "",
    response_model=TaskPage,
    dependencies=[Depends(require_reader)],
    responses=error_responses(401, 503),
)
def list_tasks(
    status: TaskStatus | None = None,
    offset: int = Query(0, ge=0, le=MAX_OFFSET),
    limit: int = Query(50, ge=1, le=500),
    state: ServiceState = Depends(get_state),
    base: str = Depends(base_url),
) -> TaskPage:
    """Tasks, newest first, optionally of one status."""
    records, total = state.store.list(status, offset, limit)
    return TaskPage(
        items=[TaskPublic.of(r, base) for r in records], total=total, offset=offset, limit=limit
    )


@router.get(
    "/{task_id}",
    response_model=TaskPublic,
    dependencies=[Depends(require_reader)],
    responses=error_responses(401, 404, 503),
)
def get_task(
    task_id: str, state: ServiceState = Depends(get_state), base: str = Depends(base_url)
) -> TaskPublic:
    """Status, progress while running, and results when done."""
    return TaskPublic.of(_record(state, task_id), base)


@router.delete(
    "/{task_id}",
    response_model=TaskPublic,
    dependencies=[Depends(require_token)],
    responses=error_responses(401, 404, 503),
)
def cancel_task(
    task_id: str, state: ServiceState = Depends(get_state), base: str = Depends(base_url)
) -> TaskPublic:
    """Cancel a queued or running task (a finished one is returned unchanged)."""
    record = _record(state, task_id)
    if not record.status.finished:
        record = state.jobs.cancel(task_id) or record
    return TaskPublic.of(record, base)


def _artifact_path(state: ServiceState, record: TaskRecord, name: str) -> Path:
    """The file of an artifact the task produced (only its own names: no path traversal)."""
    files = (record.result or {}).get("artifacts", {})
    if name not in files.values():
        raise ArtifactNotFoundError(f"task {record.id} has no artifact {name!r}")
    path = state.jobs.task_dir(record.id) / name
    if not path.is_file():
        raise ArtifactNotFoundError(f"task {record.id}: artifact {name!r} is missing on disk")
    return path


@router.get(
    "/{task_id}/artifacts/{name}",
    response_class=FileResponse,
    dependencies=[Depends(require_reader)],
    responses={200: {"content": _ARTIFACT_CONTENT}, **error_responses(401, 404, 503)},
)
def get_artifact(task_id: str, name: str, state: ServiceState = Depends(get_state)):
    """One artifact file (path.json, tracks.json, droneK.waypoints/.plan/.mission.json,
    mission.mcap, profile.png, summary.json)."""
    path = _artifact_path(state, _record(state, task_id), name)
    media = MEDIA_TYPES.get(path.suffix, "application/octet-stream")
    return FileResponse(path, media_type=media, filename=name)


@router.get(
    "/{task_id}/bundle.zip",
    response_class=Response,
    dependencies=[Depends(require_reader)],
    responses={
        200: {"content": {"application/zip": {"schema": {"type": "string", "format": "binary"}}}},
        **error_responses(401, 404, 409, 503),
    },
)
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


def _stored_missions(state: ServiceState, record: TaskRecord) -> list:
    from missions.export.formats import mission_from_json

    missions = []
    for k in (1, 2, 3):
        name = f"drone{k}.mission.json"
        path = _artifact_path(state, record, name)
        try:
            missions.append(mission_from_json(json.loads(path.read_text(encoding="utf-8"))))
        except (OSError, ValueError, KeyError, TypeError) as error:
            raise ArtifactUnreadableError(
                f"task {record.id}: artifact {name!r} is unreadable ({type(error).__name__})"
            ) from None
    return missions


def _stored_parameters(state: ServiceState, record: TaskRecord) -> list[dict[str, float]]:
    from missions.export.parameter_file import parse_parameter_file

    parameters = []
    for k in (1, 2, 3):
        name = f"drone{k}.parm"
        path = _artifact_path(state, record, name)
        try:
            parameters.append(parse_parameter_file(path.read_text(encoding="utf-8"), name))
        except (OSError, ValueError) as error:
            raise ArtifactUnreadableError(
                f"task {record.id}: artifact {name!r} is unreadable ({type(error).__name__})"
            ) from None
    return parameters


@router.post(
    "/{task_id}/upload",
    response_model=UploadPublic,
    dependencies=[Depends(require_token)],
    responses={
        **error_responses(401, 403, 404, 409, 413, 503),
        409: {
            "model": UploadPublic,
            "description": "every mission is on board, but a vehicle's parameters differ from "
            "the plan's (each named); or, with an error body, the task is not done",
        },
        502: {"model": UploadPublic, "description": "a vehicle failed (see its detail)"},
    },
)
def upload_task(
    task_id: str, body: UploadCreate, state: ServiceState = Depends(get_state)
) -> UploadPublic | JSONResponse:
    """Upload the three missions (drone k to ``vehicles[k-1]``), verify by read-back, read
    the parameters of ``drone{k}.parm`` back from each vehicle, record the outcome per
    vehicle. 502 if any vehicle failed (the others keep their mission); 409 if every mission
    is on board but a vehicle's parameters differ from the plan's (its timing holds only
    with them: load the ``.parm`` in the ground station and upload again)."""
    from missions.mavlink.policy import RetryPolicy

    record = _record(state, task_id)
    addresses = allowed_vehicles(body.vehicles, state.settings)
    if record.status is not TaskStatus.DONE:
        raise TaskNotReadyError(f"task {task_id} is {record.status}, not done")
    missions = _stored_missions(state, record)
    parameters = _stored_parameters(state, record)
    policy = RetryPolicy(deadline_s=state.settings.upload_timeout)
    vehicles = upload_missions(addresses, missions, parameters, policy)
    outcome = UploadPublic(ok=all(v.ok for v in vehicles), vehicles=vehicles)
    state.store.add_upload(task_id, outcome.model_dump())
    if any(not v.ok and not v.parameter_differences for v in vehicles):
        return JSONResponse(outcome.model_dump(), status_code=502)
    if not outcome.ok:
        return JSONResponse(outcome.model_dump(), status_code=409)
    return outcome
