"""What runs in a worker process: one task, from its row to its final status.

A job (:func:`run_job`) writes its own status changes, throttled progress and final
result to the task row, polls the row's ``cancel_requested`` flag to stop the work, and
gives the memory it freed back to the system when it ends (:mod:`service.jobs` submits it
and handles what a dead worker cannot write).
"""

from __future__ import annotations

import ctypes
import gc
import logging
import math
import tempfile
import time
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

from sqlalchemy.exc import SQLAlchemyError

from service.storage import TaskStatus, TaskStore, database_reason, make_engine

logger = logging.getLogger(__name__)

#: Why a task failed when the process running it died (SIGKILL, the OOM killer, a crash).
WORKER_DIED = (
    "the worker process running this task died (killed, e.g. out of memory); the task is "
    "not retried, since it may be what killed it"
)
#: How often a running job looks at its cancel flag and writes progress [s].
POLL_INTERVAL = 0.25
PROGRESS_INTERVAL = 0.5


@dataclass(frozen=True)
class JobSpec:
    """What a worker needs to run one task (plain, picklable data)."""

    task_id: str
    attempt: int
    request: dict[str, Any]
    database_url: str
    task_dir: str | None  #: where to write the artifacts; None: return them (module docstring)


@dataclass(frozen=True)
class JobOutcome:
    """How a job ended. ``files`` (artifact path relative to the task's directory -> bytes)
    is set when the job was not given a directory: the final status is then the caller's
    to write (``written`` False), after the files. ``written`` is False too when the
    database refused the job's write (a full disk): the service records it then."""

    status: TaskStatus
    result: dict[str, Any] | None = None
    error: str | None = None
    files: dict[str, bytes] | None = None
    written: bool = True


def run_job(spec: JobSpec) -> JobOutcome:
    """Run one task in this (worker) process.

    Imports the pipeline here so that the API process never loads planners or numba.
    """
    store = TaskStore(make_engine(spec.database_url))
    record = store.get(spec.task_id)
    if record is None or record.status.finished or record.attempt != spec.attempt:
        return JobOutcome(record.status if record else TaskStatus.FAILED)
    if record.status is not TaskStatus.QUEUED:
        # Started before at this attempt: the worker running it died and the executor (Dask
        # reschedules a lost worker's tasks) runs it again. Not retried: it may be what
        # killed the worker.
        return _finish(store, spec, TaskStatus.FAILED, None, WORKER_DIED)
    try:
        if spec.task_dir is not None:
            return _run(spec, store, Path(spec.task_dir))
        with tempfile.TemporaryDirectory(prefix=f"flycrane-{spec.task_id}-") as scratch:
            outcome = _run(spec, store, Path(scratch))
            files = {
                path.relative_to(scratch).as_posix(): path.read_bytes()
                for path in sorted(Path(scratch).rglob("*"))
                if path.is_file()
            }
        return replace(outcome, files=files)
    finally:
        store.engine.dispose()
        _give_back_memory()


def _give_back_memory() -> None:
    """Return what a finished job freed to the system: the C allocator keeps freed heap for
    reuse, so a worker that built a large mission would hold it until its next job."""
    gc.collect()
    try:
        ctypes.CDLL("libc.so.6").malloc_trim(0)
    except (OSError, AttributeError):  # not glibc: nothing to trim
        pass


def _finish(
    store: TaskStore,
    spec: JobSpec,
    status: TaskStatus,
    result: dict[str, Any] | None,
    error: str | None,
) -> JobOutcome:
    """Write the job's outcome; if the database refuses (a full disk), return it unwritten
    for the service to record (:meth:`JobManager.reconcile`)."""
    try:
        final = store.finish(spec.task_id, spec.attempt, status, result, error)
    except SQLAlchemyError as failure:
        logger.error("task %s: outcome not recorded: %s", spec.task_id, database_reason(failure))
        return JobOutcome(status, result, error, written=False)
    return JobOutcome(final.status if final else status, result, error)


def _run(spec: JobSpec, store: TaskStore, task_dir: Path) -> JobOutcome:
    """Plan and export the task into ``task_dir``; its final status is written here only
    when ``task_dir`` is the task's own (``spec.task_dir``)."""
    from flycrane.planning.result import PlanningProgress
    from missions.task.pipeline import run_task
    from missions.task.spec import TaskSpec, require_served_task

    stop_flag, checked = False, -math.inf  # the first call reads the flag
    written_at, written_stage = 0.0, ""

    def should_stop() -> bool:
        nonlocal stop_flag, checked
        now = time.monotonic()
        if not stop_flag and now - checked >= POLL_INTERVAL:
            current = store.get(spec.task_id)
            stop_flag = bool(
                current is None or current.cancel_requested or current.attempt != spec.attempt
            )
            checked = now
        return stop_flag

    def progress(stage: str, report: PlanningProgress | None) -> None:
        nonlocal written_at, written_stage
        now = time.monotonic()
        if stage == written_stage and now - written_at < PROGRESS_INTERVAL:
            return
        data: dict[str, Any] = {"stage": stage}
        if report is not None:
            data.update(
                iterations=report.expansion_attempts,
                nodes=report.nodes,
                distance_to_goal=report.distance_to_goal,
                elapsed=report.elapsed,
            )
        store.update(spec.task_id, spec.attempt, status=TaskStatus(stage), progress=data)
        written_at, written_stage = now, stage

    if should_stop():
        return _finish(store, spec, TaskStatus.CANCELLED, None, "cancelled before start")
    try:
        task = TaskSpec.model_validate(spec.request)
        require_served_task(task)  # rows written by an older version are checked again
        outcome = run_task(task, task_dir, progress=progress, should_stop=should_stop)
        status, result, error = TaskStatus(outcome.status), outcome.as_dict(), outcome.reason
    except SQLAlchemyError as failure:  # a progress report the database refused
        logger.exception("task %s failed", spec.task_id)
        reason = f"the database refused a write: {database_reason(failure)}"
        status, result, error = TaskStatus.FAILED, None, reason
    except Exception as failure:
        logger.exception("task %s failed", spec.task_id)
        status, result, error = TaskStatus.FAILED, None, f"{type(failure).__name__}: {failure}"
    if spec.task_dir is None:
        return JobOutcome(status, result, error or None, written=False)
    return _finish(store, spec, status, result, error or None)
