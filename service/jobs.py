"""Background execution of tasks: a bounded queue over an Executor, cancellation, progress.

The database is the single source of truth. A job (:func:`run_job`, run in a worker
process) writes its own status changes, throttled progress and final result to the task
row, and polls the row's ``cancel_requested`` flag to stop the planner; the API process
only submits, counts what is in flight (to refuse work beyond ``max_queued_tasks`` with
503) and, if a worker dies without writing a result, marks the task failed.

Any :class:`concurrent.futures.Executor` runs the jobs (the local process pool by default,
see :mod:`flycrane.execution`), so a distributed executor can take over unchanged as long as
its workers reach the same database and artifact directory.
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable
from concurrent.futures import Executor, Future
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from service.errors import ServiceBusyError
from service.metrics import ServiceMetrics
from service.storage import TaskRecord, TaskStatus, TaskStore, make_engine

logger = logging.getLogger(__name__)

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
    task_dir: str


def run_job(spec: JobSpec) -> str:
    """Run one task in this (worker) process; returns the final status.

    Imports the pipeline here so that the API process never loads planners or numba.
    """
    from flycrane.planning.result import PlanningProgress
    from missions.pipeline import run_task
    from missions.task import TaskSpec

    store = TaskStore(make_engine(spec.database_url))
    record = store.get(spec.task_id)
    if record is None or record.status.finished or record.attempt != spec.attempt:
        return record.status.value if record else TaskStatus.FAILED.value
    stopped = {"flag": record.cancel_requested, "checked": time.monotonic()}
    written = {"at": 0.0, "stage": ""}

    def should_stop() -> bool:
        now = time.monotonic()
        if not stopped["flag"] and now - stopped["checked"] >= POLL_INTERVAL:
            current = store.get(spec.task_id)
            stopped["flag"] = bool(
                current is None or current.cancel_requested or current.attempt != spec.attempt
            )
            stopped["checked"] = now
        return stopped["flag"]

    def progress(stage: str, report: PlanningProgress | None) -> None:
        now = time.monotonic()
        if stage == written["stage"] and now - written["at"] < PROGRESS_INTERVAL:
            return
        data = {"stage": stage}
        if report is not None:
            data.update(
                iterations=report.expansion_attempts,
                nodes=report.nodes,
                distance_to_goal=report.distance_to_goal,
                elapsed=report.elapsed,
            )
        store.update(spec.task_id, spec.attempt, status=TaskStatus(stage), progress=data)
        written.update(at=now, stage=stage)

    if should_stop():
        store.update(
            spec.task_id, spec.attempt, status=TaskStatus.CANCELLED, error="cancelled before start"
        )
        return TaskStatus.CANCELLED.value
    try:
        outcome = run_task(
            TaskSpec.model_validate(spec.request),
            spec.task_dir,
            progress=progress,
            should_stop=should_stop,
        )
        status, result, error = TaskStatus(outcome.status), outcome.as_dict(), outcome.reason
    except Exception as failure:
        logger.exception("task %s failed", spec.task_id)
        status, result, error = TaskStatus.FAILED, None, f"{type(failure).__name__}: {failure}"
    store.update(spec.task_id, spec.attempt, status=status, result=result, error=error or None)
    return status.value


class JobManager:
    """Submits tasks to an executor, at most ``capacity`` in flight."""

    def __init__(
        self,
        store: TaskStore,
        executor: Executor,
        database_url: str,
        tasks_dir: Path,
        capacity: int,
        metrics: ServiceMetrics,
        job: Callable[[JobSpec], str] = run_job,
    ) -> None:
        self.store, self.executor, self.database_url = store, executor, database_url
        self.tasks_dir, self.capacity, self.metrics, self.job = tasks_dir, capacity, metrics, job
        self._futures: dict[str, Future] = {}
        self._lock = threading.Lock()

    @property
    def in_flight(self) -> int:
        with self._lock:
            return len(self._futures)

    def task_dir(self, task_id: str) -> Path:
        return self.tasks_dir / task_id

    def reserve(self) -> None:
        """Raise :class:`ServiceBusyError` if no slot is free (before storing a task)."""
        if self.in_flight >= self.capacity:
            raise ServiceBusyError(
                f"{self.capacity} tasks are queued or running; retry later",
                headers={"Retry-After": "10"},
            )

    def submit(self, record: TaskRecord) -> None:
        """Queue a stored task (its row already says queued)."""
        spec = JobSpec(
            record.id,
            record.attempt,
            record.request,
            self.database_url,
            str(self.task_dir(record.id)),
        )
        future = self.executor.submit(self.job, spec)
        with self._lock:
            self._futures[record.id] = future
        future.add_done_callback(lambda done, task_id=record.id: self._finished(task_id, done))

    def cancel(self, task_id: str) -> TaskRecord | None:
        """Ask a task to stop: a queued one is dropped, a running one stops at its next poll."""
        record = self.store.update(task_id, cancel_requested=True)
        with self._lock:
            future = self._futures.get(task_id)
        if future is not None and future.cancel():
            record = self.store.update(
                task_id, status=TaskStatus.CANCELLED, error="cancelled while queued"
            )
        return record

    def resume_unfinished(self) -> list[str]:
        """After a restart: queue again every task that was queued or running."""
        resumed = []
        for record in self.store.unfinished():
            record = self.store.update(
                record.id,
                status=TaskStatus.QUEUED,
                attempt=record.attempt + 1,
                progress={"stage": "queued", "resumed": True},
            )
            if record.cancel_requested:
                self.store.update(
                    record.id, status=TaskStatus.CANCELLED, error="cancelled before a restart"
                )
                continue
            self.submit(record)
            resumed.append(record.id)
        return resumed

    def _finished(self, task_id: str, future: Future) -> None:
        with self._lock:
            self._futures.pop(task_id, None)
        if future.cancelled():
            return
        failure = future.exception()
        if failure is not None:  # the worker died or could not even start the job
            self.store.update(
                task_id,
                status=TaskStatus.FAILED,
                error=f"worker failed: {type(failure).__name__}: {failure}",
            )
        record = self.store.get(task_id)
        if record and record.result:
            seconds = record.result.get("planner_statistics", {}).get("time")
            if seconds is not None:
                self.metrics.planning_seconds.observe(seconds)
