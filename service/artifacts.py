"""A stored task's artifacts: which files a task may serve, its missions and parameters for
an upload, its bundle and its viewer document.

Every file is read through the task's directory (:class:`~missions.task.directory.
TaskDirectory`); a file that is missing or unusable on disk is a 404 or a 409 naming it.
"""

from __future__ import annotations

import io
import zipfile
from collections.abc import Callable
from pathlib import Path
from typing import TypeVar

from missions.export.items import DroneMission
from missions.task.directory import DRONES, TaskDirectory, TaskDirectoryError, mission_file
from missions.task.spec import TaskSpec
from missions.viewer import ViewUnavailableError, standalone_page, view_document
from service.errors import ArtifactNotFoundError, ArtifactUnreadableError, TaskNotReadyError
from service.jobs import JobManager
from service.storage import TaskRecord, TaskStatus

T = TypeVar("T")
#: Media types of the artifacts, by extension.
MEDIA_TYPES = {
    ".json": "application/json",
    ".plan": "application/json",
    ".waypoints": "text/plain",
    ".mcap": "application/octet-stream",
    ".png": "image/png",
}


def media_type(path: Path) -> str:
    return MEDIA_TYPES.get(path.suffix, "application/octet-stream")


def artifact_path(jobs: JobManager, record: TaskRecord, name: str) -> Path:
    """The file of an artifact the task produced (only its own names: no path traversal).

    Raises
    ------
    ArtifactNotFoundError
        Not one of the task's artifacts, or gone from the disk.
    """
    files = (record.result or {}).get("artifacts", {})
    if name not in files.values():
        raise ArtifactNotFoundError(f"task {record.id} has no artifact {name!r}")
    path = jobs.task_dir(record.id) / name
    if not path.is_file():
        raise ArtifactNotFoundError(f"task {record.id}: artifact {name!r} is missing on disk")
    return path


def stored_missions(
    jobs: JobManager, record: TaskRecord
) -> tuple[list[DroneMission], list[dict[str, float]]]:
    """The three missions of a done task and the parameters each assumes.

    Raises
    ------
    TaskNotReadyError
        The task is not done.
    ArtifactNotFoundError, ArtifactUnreadableError
        A mission or parameter file is missing or unusable (it names the file).
    """
    if record.status is not TaskStatus.DONE:
        raise TaskNotReadyError(f"task {record.id} is {record.status}, not done")
    directory = TaskDirectory(jobs.task_dir(record.id))

    def read(suffix: str, reader: Callable[[list[int]], list[T]]) -> list[T]:
        """Each drone's file, in turn: among the task's artifacts, on disk, usable."""
        files = []
        for k in DRONES:
            artifact_path(jobs, record, mission_file(k, suffix))
            try:
                files += reader([k])
            except TaskDirectoryError as error:
                raise ArtifactUnreadableError(
                    f"task {record.id}: artifact {error.name!r} is unreadable"
                ) from None
        return files

    return read("mission.json", directory.missions), read("parm", directory.parameters)


def view_of(jobs: JobManager, record: TaskRecord) -> dict:
    """The viewer document of a done task (docs/viewer.md).

    Raises
    ------
    TaskNotReadyError, ArtifactNotFoundError
    """
    if record.status is not TaskStatus.DONE:
        raise TaskNotReadyError(f"task {record.id} is {record.status}, not done: nothing to view")
    try:
        return view_document(TaskSpec.model_validate(record.request), jobs.task_dir(record.id))
    except ViewUnavailableError as error:
        raise ArtifactNotFoundError(str(error)) from None


def bundle(jobs: JobManager, record: TaskRecord) -> bytes:
    """Every artifact of a task in one zip, with view.html (the viewer, offline) if done.

    Raises
    ------
    TaskNotReadyError
        The task has no artifacts.
    """
    files = (record.result or {}).get("artifacts", {})
    if not files:
        raise TaskNotReadyError(f"task {record.id} has no artifacts (status {record.status})")
    buffer = io.BytesIO()
    with zipfile.ZipFile(buffer, "w", zipfile.ZIP_DEFLATED) as archive:
        for name in sorted(set(files.values())):
            archive.write(artifact_path(jobs, record, name), arcname=name)
        if record.status is TaskStatus.DONE:  # the viewer, standalone (docs/viewer.md)
            archive.writestr("view.html", standalone_page(view_of(jobs, record)))
    return buffer.getvalue()
