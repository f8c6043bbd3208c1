"""The plan viewer in the browser: a task's page, its data, the task list, the page's files.

- ``GET /v1/tasks/{id}/view``: the viewer page of a done task (HTML);
- ``GET /v1/tasks/{id}/view.json``: the document that page draws (docs/viewer.md);
- ``GET /v1/viewer``: the tasks, newest first, linking to their views and bundles;
- ``GET /v1/viewer/static/{path}``: the page's script, styles and vendored libraries, open
  to all (no task data in them), as the API docs are.

Each page carries a Content-Security-Policy that runs only this server's scripts and its
own import map (:func:`service.security.page_policy`).

Pages link to each other and to the static files by relative URLs, so they work behind a
proxy that mounts the service under a path prefix.
"""

from __future__ import annotations

import html

from fastapi import APIRouter, Query
from fastapi.responses import FileResponse, HTMLResponse

from missions.viewer import served_page, static_file
from missions.viewer.page import ListedTask, task_list_page
from service.artifacts import view_file, view_of
from service.deps import ServiceState, StateDep
from service.errors import ArtifactNotFoundError, TaskNotFoundError, error_responses
from service.security import CSP, page_policy
from service.storage import MAX_OFFSET, TaskRecord, TaskStatus

router = APIRouter(tags=["viewer"])
#: The page's files carry no task data: open to all, as the API docs are (``create_app``).
static_router = APIRouter(tags=["viewer"], responses=error_responses(404))

#: The page's files as seen from /v1/tasks/{id}/view and from /v1/viewer.
_STATIC_FROM_TASK, _STATIC_FROM_LIST = "../../viewer/static/", "viewer/static/"


def _record(state: ServiceState, task_id: str) -> TaskRecord:
    record = state.store.get(task_id)
    if record is None:
        raise TaskNotFoundError(f"no task {task_id!r}")
    return record


@router.get("/v1/tasks/{task_id}/view", response_class=HTMLResponse)
def view_task(task_id: str, state: StateDep) -> HTMLResponse:
    """The viewer page of a done task: scene, planned (and flown) motion, profiles."""
    page = served_page(view_of(state.jobs, _record(state, task_id)), _STATIC_FROM_TASK,
                       "../../viewer")  # fmt: skip
    return HTMLResponse(page, headers={CSP: page_policy(page)})


@router.get("/v1/tasks/{task_id}/view.json", response_class=FileResponse)
def view_task_data(task_id: str, state: StateDep) -> FileResponse:
    """The viewer's document of a done task (docs/viewer.md), made once, then from disk."""
    return FileResponse(
        view_file(state.jobs, _record(state, task_id)), media_type="application/json"
    )


def _listed(record: TaskRecord) -> ListedTask:
    result = record.result or {}
    mission = result.get("mission") or {}
    if record.status is TaskStatus.DONE and mission:
        summary = f"{mission['waypoints']} waypoints, {mission['duration']:.1f} s"
    else:
        summary = record.error or ""
    done = record.status is TaskStatus.DONE
    return ListedTask(
        name=record.request.get("name") or record.id,
        status=record.status.value,
        created=record.created_at.strftime("%Y-%m-%d %H:%M:%S"),
        summary=summary,
        view_url=f"tasks/{record.id}/view" if done else "",
        bundle_url=f"tasks/{record.id}/bundle.zip" if result.get("artifacts") else "",
    )


@router.get("/v1/viewer", response_class=HTMLResponse)
def task_list(
    state: StateDep,
    offset: int = Query(0, ge=0, le=MAX_OFFSET),
    limit: int = Query(50, ge=1, le=500),
) -> HTMLResponse:
    """The tasks, newest first, with links to their views and bundles."""
    records, total = state.store.list(None, offset, limit)
    links = []
    if offset > 0:
        links.append(f'<a href="?offset={max(offset - limit, 0)}&amp;limit={limit}">newer</a>')
    if offset + limit < total:
        links.append(f'<a href="?offset={offset + limit}&amp;limit={limit}">older</a>')
    shown = f"{offset + 1}-{offset + len(records)} of {total}" if records else f"0 of {total}"
    pages = " ".join([html.escape(shown), *links])
    page = task_list_page([_listed(r) for r in records], _STATIC_FROM_LIST, pages)
    return HTMLResponse(page, headers={CSP: page_policy(page)})


@static_router.get("/v1/viewer/static/{name:path}")
def viewer_static(name: str) -> FileResponse:
    """A file of the viewer page (its script, styles, vendored libraries and licenses)."""
    path = static_file(name)
    if path is None:
        raise ArtifactNotFoundError(f"the viewer has no file {name!r}")
    return FileResponse(path)
