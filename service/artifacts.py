"""A stored task's artifacts: which files a task may serve, its missions and parameters for
an upload, its bundle and its viewer document.

Every file is read through the task's directory (:class:`~missions.task.directory.
TaskDirectory`); a file that is missing or unusable on disk is a 404 or a 409 naming it.
"""

from __future__ import annotations

import json
import os
import threading
import zipfile
from collections.abc import Callable
from pathlib import Path
from typing import TypeVar

from missions.export.items import DroneMission
from missions.task.directory import TaskDirectory, TaskDirectoryError, mission_file
from missions.task.documents import DRONES
from missions.task.spec import TaskSpec
from missions.viewer import PAGE_FILE, ViewUnavailableError, standalone_page, view_document
from service.errors import (
    ArtifactNotFoundError,
    ArtifactUnreadableError,
    ServiceBusyError,
    TaskNotReadyError,
)
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


#: Files the service derives from a done task's files, made on the first request and kept
#: beside them until one of those changes.
DERIVED_DIR = "served"
VIEW_FILE, BUNDLE_FILE = "view.json", "bundle.zip"
#: One derived file is made at a time: eight clients asking for one bundle make it once,
#: and a burst of requests does not hold eight documents in memory.
_MAKING = threading.RLock()  # a bundle makes the view document inside


def _derived(jobs: JobManager, record: TaskRecord, name: str, make: Callable[[Path], None]) -> Path:
    """The file ``name`` derived from the task, made by ``make(path)`` when missing or
    older than a file of the task (a flight's ``flown.json`` may be added beside it).

    Raises
    ------
    ServiceBusyError
        It could not be written (a full disk): nothing half-written is kept.
    """
    task_dir = jobs.task_dir(record.id)
    path = task_dir / DERIVED_DIR / name

    def fresh() -> bool:
        if not path.is_file():
            return False
        made = path.stat().st_mtime_ns
        return all(f.stat().st_mtime_ns < made for f in task_dir.iterdir() if f.is_file())

    if fresh():
        return path
    with _MAKING:
        if fresh():
            return path
        part = path.with_name(f".{name}.part")
        try:
            path.parent.mkdir(exist_ok=True)
            make(part)
            os.replace(part, path)
        except OSError as error:
            part.unlink(missing_ok=True)
            raise ServiceBusyError(f"task {record.id}: cannot write its {name}: {error}") from None
    return path


def view_file(jobs: JobManager, record: TaskRecord) -> Path:
    """The viewer document of a done task (docs/viewer.md), as a JSON file.

    Raises
    ------
    TaskNotReadyError, ArtifactNotFoundError, ServiceBusyError
    """
    if record.status is not TaskStatus.DONE:
        raise TaskNotReadyError(f"task {record.id} is {record.status}, not done: nothing to view")

    def make(path: Path) -> None:
        try:
            document = view_document(
                TaskSpec.model_validate(record.request), jobs.task_dir(record.id)
            )
        except ViewUnavailableError as error:
            raise ArtifactNotFoundError(str(error)) from None
        path.write_text(json.dumps(document), encoding="utf-8")

    return _derived(jobs, record, VIEW_FILE, make)


def view_of(jobs: JobManager, record: TaskRecord) -> dict:
    """The viewer document of a done task (:func:`view_file`, read)."""
    return json.loads(view_file(jobs, record).read_text(encoding="utf-8"))


def bundle_file(jobs: JobManager, record: TaskRecord) -> Path:
    """Every artifact of a task in one zip file, with view.html (the viewer, offline) if
    done; written to disk once and streamed from there.

    Raises
    ------
    TaskNotReadyError
        The task has no artifacts.
    ServiceBusyError
        The zip could not be written.
    """
    files = (record.result or {}).get("artifacts", {})
    if not files or not record.status.finished:
        raise TaskNotReadyError(f"task {record.id} has no artifacts (status {record.status})")

    def make(path: Path) -> None:
        paths = {name: artifact_path(jobs, record, name) for name in sorted(set(files.values()))}
        page = standalone_page(view_of(jobs, record)) if record.status is TaskStatus.DONE else None
        with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED) as archive:
            for name, source in paths.items():
                archive.write(source, arcname=name)
            if page is not None:  # the viewer, standalone (docs/viewer.md)
                archive.writestr(PAGE_FILE, page)

    return _derived(jobs, record, BUNDLE_FILE, make)
