"""/v1/tasks: submit, inspect, cancel, download artifacts, upload missions to vehicles.

Handlers are plain functions: FastAPI runs them in its thread pool, so a slow or locked
database holds one thread, never the event loop (a locked SQLite answers 503 after
``database_busy_timeout``), and a task's body is validated there, not by FastAPI on the
event loop (:data:`service.schemas.TaskBody`). Uploads, which wait for vehicles, run on
threads of their own instead (:class:`service.uploads.UploadRunner`). What they do lives in
:mod:`service.artifacts` and :mod:`service.uploads`.
"""

from __future__ import annotations

import asyncio
from functools import partial
from typing import Annotated, Any

from fastapi import APIRouter, Query
from fastapi.concurrency import run_in_threadpool
from fastapi.responses import FileResponse, JSONResponse
from pydantic import BeforeValidator

from flycrane.errors import FieldProblem, InputError
from missions.task.resolve import resolve_task
from missions.task.spec import TaskSpec, require_served_task
from service import uploads
from service.artifacts import MEDIA_TYPES, artifact_path, bundle_file, media_type
from service.deps import READ, WRITE, BaseUrl, ServiceState, StateDep
from service.errors import TaskNotFoundError, error_responses
from service.schemas import (
    TaskAccepted,
    TaskBody,
    TaskPage,
    TaskPublic,
    UploadBody,
    UploadCreate,
    UploadPublic,
    validated,
)
from service.storage import MAX_OFFSET, TaskRecord, TaskStatus

router = APIRouter(prefix="/v1/tasks", tags=["tasks"])

_FILE = {"type": "string", "format": "binary"}
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
    limit = state.settings.max_time_budget
    problems = [
        FieldProblem(f"planner.{name}", f"at most {limit:g} s here")
        for name in ("time_budget", "improve_time")
        if getattr(task.planner, name) > limit
    ]
    if problems:
        raise InputError(problems)
    require_served_task(task)


@router.post(
    "",
    status_code=202,
    response_model=TaskAccepted,
    dependencies=WRITE,
    responses=error_responses(401, 413, 503),
)
def create_task(body: TaskBody, state: StateDep, base: BaseUrl) -> TaskAccepted:
    """Validate a task (start and goal included), store it, queue it; 202 with its URL."""
    try:
        task = validated(TaskSpec, body)
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


def _blank_means(default: Any) -> BeforeValidator:
    """An empty query parameter (``?status=``, as the README's table writes them) is read as
    if it were left out: ``default``."""
    return BeforeValidator(lambda value: default if value == "" else value)


@router.get(
    "",
    response_model=TaskPage,
    dependencies=READ,
    responses=error_responses(401, 503),
)
def list_tasks(
    state: StateDep,
    base: BaseUrl,
    status: Annotated[TaskStatus | None, _blank_means(None)] = None,
    offset: Annotated[int, Query(ge=0, le=MAX_OFFSET), _blank_means(0)] = 0,
    limit: Annotated[int, Query(ge=1, le=500), _blank_means(50)] = 50,
) -> TaskPage:
    """Tasks, newest first, optionally of one status (an empty parameter is as if left
    out: any status, the first page of 50)."""
    records, total = state.store.list(status, offset, limit)
    return TaskPage(
        items=[TaskPublic.of(r, base) for r in records], total=total, offset=offset, limit=limit
    )


@router.get(
    "/{task_id}",
    response_model=TaskPublic,
    dependencies=READ,
    responses=error_responses(401, 404, 503),
)
def get_task(task_id: str, state: StateDep, base: BaseUrl) -> TaskPublic:
    """Status, progress while running, and results when done."""
    return TaskPublic.of(_record(state, task_id), base)


@router.delete(
    "/{task_id}",
    response_model=TaskPublic,
    dependencies=WRITE,
    responses=error_responses(401, 404, 503),
)
def cancel_task(task_id: str, state: StateDep, base: BaseUrl) -> TaskPublic:
    """Cancel a queued or running task (a finished one is returned unchanged)."""
    record = _record(state, task_id)
    if not record.status.finished:
        record = state.jobs.cancel(task_id) or record
    return TaskPublic.of(record, base)


@router.get(
    "/{task_id}/artifacts/{name}",
    response_class=FileResponse,
    dependencies=READ,
    responses={200: {"content": _ARTIFACT_CONTENT}, **error_responses(401, 404, 503)},
)
def get_artifact(task_id: str, name: str, state: StateDep):
    """One artifact file (path.json, tracks.json, droneK.waypoints/.plan/.mission.json,
    mission.mcap, profile.png, summary.json)."""
    path = artifact_path(state.jobs, _record(state, task_id), name)
    return FileResponse(path, media_type=media_type(path), filename=name)


@router.get(
    "/{task_id}/bundle.zip",
    response_class=FileResponse,
    dependencies=READ,
    responses={
        200: {"content": {"application/zip": {"schema": {"type": "string", "format": "binary"}}}},
        **error_responses(401, 404, 409, 503),
    },
)
def get_bundle(task_id: str, state: StateDep) -> FileResponse:
    """Every artifact of a task in one zip, with view.html, the viewer page that opens
    offline (made once, then streamed from disk)."""
    path = bundle_file(state.jobs, _record(state, task_id))
    return FileResponse(path, media_type="application/zip", filename=f"{task_id}.zip")


@router.post(
    "/{task_id}/upload",
    response_model=UploadPublic,
    dependencies=WRITE,
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
async def upload_task(
    task_id: str, raw: UploadBody, state: StateDep
) -> UploadPublic | JSONResponse:
    """Upload the three missions (drone k to ``vehicles[k-1]``), verify by read-back, read
    the parameters of ``drone{k}.parm`` back from each vehicle, record the outcome per
    vehicle. 502 if any vehicle failed (the others keep their mission); 409 if every mission
    is on board but a vehicle's parameters differ from the plan's (its timing holds only
    with them: load the ``.parm`` in the ground station and upload again); 422 if two
    addresses reach the same vehicle (nothing is sent). It runs off the request threads,
    at most ``FLYCRANE_MAX_CONCURRENT_UPLOADS`` at once (503 beyond), each vehicle's upload
    within ``FLYCRANE_UPLOAD_TIMEOUT``."""
    body = await run_in_threadpool(validated, UploadCreate, raw)
    work = partial(
        uploads.upload_task, task_id, body.vehicles, state.settings, state.jobs, state.store
    )
    outcome = await asyncio.wrap_future(state.uploads.submit(work))
    if any(not v.ok and not v.parameter_differences for v in outcome.vehicles):
        return JSONResponse(outcome.model_dump(mode="json"), status_code=502)
    if not outcome.ok:
        return JSONResponse(outcome.model_dump(mode="json"), status_code=409)
    return outcome
