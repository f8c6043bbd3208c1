"""Background execution of tasks: a bounded queue over an Executor, cancellation, progress.

The database is the single source of truth. A job (:func:`service.worker.run_job`, run in a
worker process) writes its own status changes, throttled progress and final result to the
task row, and polls the row's ``cancel_requested`` flag to stop the planner; the API process
only submits, counts what is in flight (to refuse work beyond ``max_queued_tasks`` with
503) and, if a worker dies without writing a result, marks the task failed.

Any :class:`concurrent.futures.Executor` runs the jobs (the local process pool by default,
a Dask cluster with ``FLYCRANE_EXECUTOR=dask://host:port``, see :mod:`flycrane.execution`).
Its workers must reach the database; they need not share the service's disk: without
``shared_disk`` a job plans into a scratch directory of its worker and returns the artifacts
with its outcome, and the service writes them into the task's directory before it writes
the final status (so a task reads ``done`` only once its files are there).
"""

from __future__ import annotations

import logging
import threading
from collections.abc import Callable, Iterator
from concurrent.futures import BrokenExecutor, Executor, Future
from contextlib import contextmanager
from dataclasses import dataclass
from functools import partial
from pathlib import Path
from typing import Any

from sqlalchemy.exc import SQLAlchemyError

from flycrane.execution import stop_executor
from service.errors import ServiceBusyError
from service.metrics import ServiceMetrics
from service.storage import TaskRecord, TaskStatus, TaskStore, database_reason
from service.worker import WORKER_DIED, JobOutcome, JobSpec, run_job

logger = logging.getLogger(__name__)


@dataclass(frozen=True)
class _Final:
    """A job's outcome, as :meth:`TaskStore.finish` writes it."""

    attempt: int
    status: TaskStatus
    result: dict[str, Any] | None
    error: str | None


class JobManager:
    """Submits tasks to an executor, at most ``capacity`` in flight.

    A local process pool breaks for good when one of its workers dies: every job in it
    fails with ``BrokenProcessPool`` and it accepts no more. The manager then starts a new
    pool (``executor_factory``), fails the task that was running with :data:`WORKER_DIED`
    and queues the others again on the new pool. Without a factory (an executor the caller
    owns) the tasks fail with the reason and :attr:`healthy` turns false. On a Dask cluster
    a lost worker's tasks are run again by the scheduler, and :func:`run_job` fails the one
    that had started with the same reason.

    ``shared_disk`` False: the executor's workers cannot write the tasks' directories; jobs
    return their artifacts and the manager writes them (module docstring).

    An outcome the database refuses to record (a full disk: the job's own write failed, then
    the manager's) is kept and written again every :attr:`reconcile_interval` seconds
    (:meth:`reconcile`, called by the application), until it is; meanwhile :attr:`problems`
    says so (``/healthz`` answers 503) and a cancel ends the task at once.
    """

    #: How often outcomes the database refused are written again [s].
    reconcile_interval = 2.0

    def __init__(
        self,
        store: TaskStore,
        executor: Executor,
        database_url: str,
        tasks_dir: Path,
        capacity: int,
        metrics: ServiceMetrics,
        executor_factory: Callable[[], Executor] | None = None,
        shared_disk: bool = True,
    ) -> None:
        self.store, self.executor, self.database_url = store, executor, database_url
        self.tasks_dir, self.capacity, self.metrics = tasks_dir, capacity, metrics
        self.executor_factory, self.shared_disk = executor_factory, shared_disk
        self.replaced_pools = 0
        self._futures: dict[str, tuple[Future, Executor]] = {}  #: task id -> its job
        self._broken: Executor | None = None
        self._stopping = False
        self._reserved = 0  #: slots taken by tasks being stored (slot())
        self._unwritten: dict[str, _Final] = {}  #: task id -> outcome the database refused
        self._refusal = ""  #: the database's reason, last time it refused
        self._lock = threading.RLock()

    @property
    def in_flight(self) -> int:
        with self._lock:
            return len(self._futures)

    @property
    def healthy(self) -> bool:
        """Whether new tasks can run (false once a pool broke and could not be replaced)."""
        with self._lock:
            return self._broken is None and not self._stopping

    @property
    def problems(self) -> list[str]:
        """Why tasks cannot be recorded now (empty when they can)."""
        with self._lock:
            if not self._unwritten:
                return []
            return [
                f"the database refused to record how {len(self._unwritten)} task(s) ended "
                f"({self._refusal}); retrying every {self.reconcile_interval:g} s"
            ]

    def task_dir(self, task_id: str) -> Path:
        return self.tasks_dir / task_id

    @contextmanager
    def slot(self) -> Iterator[None]:
        """Hold one of the ``capacity`` slots while a new task is stored and submitted.

        Requests run in parallel threads: the slot is counted from here on, so that two of
        them cannot both take the last one.

        Raises
        ------
        ServiceBusyError
            If no slot is free, or no pool can run tasks.
        """
        with self._lock:
            if not self.healthy:
                raise ServiceBusyError(
                    "no worker pool can run tasks (see /healthz); retry later",
                    headers={"Retry-After": "30"},
                )
            if len(self._futures) + self._reserved >= self.capacity:
                raise ServiceBusyError(
                    f"{self.capacity} tasks are queued or running; retry later",
                    headers={"Retry-After": "10"},
                )
            self._reserved += 1
        try:
            yield
        finally:
            with self._lock:
                self._reserved -= 1

    def submit(self, record: TaskRecord) -> None:
        """Queue a stored task (its row already says queued).

        Raises
        ------
        ServiceBusyError
            If no pool takes it (the row is then marked failed with the reason).
        """
        spec = JobSpec(
            record.id,
            record.attempt,
            record.request,
            self.database_url,
            str(self.task_dir(record.id)) if self.shared_disk else None,
        )
        with self._lock:
            future, executor = None, self.executor
            for _ in range(2):  # a pool found broken here is replaced once
                executor = self.executor
                try:
                    future = executor.submit(run_job, spec)
                    break
                except (BrokenExecutor, RuntimeError):  # broken, or shut down
                    if not self._replace(executor):
                        break
            if future is None:
                self.store.update(
                    record.id, status=TaskStatus.FAILED, error="no worker pool could take it"
                )
                raise ServiceBusyError(
                    "no worker pool can run tasks (see /healthz); retry later",
                    headers={"Retry-After": "30"},
                )
            self._futures[record.id] = (future, executor)
        future.add_done_callback(partial(self._finished, spec, executor))

    def cancel(self, task_id: str) -> TaskRecord | None:
        """Ask a task to stop: a queued one is dropped, a running one stops at its next poll,
        one that no job runs any more (its outcome unrecorded, or lost) ends at once.

        Raises
        ------
        sqlalchemy.exc.SQLAlchemyError
            If the database refuses the request (the API answers 503).
        """
        record = self.store.update(task_id, cancel_requested=True)
        if record is None or record.status.finished:
            return record
        with self._lock:
            future, _ = self._futures.get(task_id, (None, None))
            unwritten = self._unwritten.get(task_id)
        if unwritten is not None:  # the job ended: its outcome, cancelled (store.finish)
            self._record(task_id, unwritten)
            return self.store.get(task_id)
        if future is None:  # no job of ours runs it: nobody else would end it
            return self.store.update(
                task_id, status=TaskStatus.CANCELLED, error="cancelled (no job was running it)"
            )
        # Only a job not yet started may be dropped: a Dask future is cancelled even while
        # it runs (its worker goes on), and the job then stops itself at its next poll.
        if record.status is TaskStatus.QUEUED and future.cancel():
            record = self.store.update(
                task_id, status=TaskStatus.CANCELLED, error="cancelled while queued"
            )
        return record

    def reconcile(self) -> None:
        """Write again the outcomes the database refused (every :attr:`reconcile_interval`
        seconds, from the application's lifespan)."""
        with self._lock:
            pending = list(self._unwritten.items())
        for task_id, final in pending:
            if not self._record(task_id, final):
                return  # still refused: the others would be too

    def _record(self, task_id: str, final: _Final) -> bool:
        """Write a job's outcome (a cancel asked for meanwhile wins, :meth:`TaskStore.finish`);
        keep it for :meth:`reconcile` if the database refuses. Whether it was written."""
        try:
            self.store.finish(task_id, final.attempt, final.status, final.result, final.error)
        except SQLAlchemyError as failure:
            reason = database_reason(failure)
            logger.error("task %s: outcome not recorded (%s); retrying", task_id, reason)
            with self._lock:
                self._unwritten[task_id] = final
                self._refusal = reason
            return False
        with self._lock:
            if self._unwritten.get(task_id) is final:
                del self._unwritten[task_id]
        return True

    def resume_unfinished(self) -> list[str]:
        """After a restart: queue again every task that was queued or running."""
        resumed = []
        for found in self.store.unfinished():
            record = self.store.update(
                found.id,
                status=TaskStatus.QUEUED,
                attempt=found.attempt + 1,
                progress={"stage": "queued", "resumed": True},
            )
            if record is None:
                continue
            if record.cancel_requested:
                self.store.update(
                    record.id, status=TaskStatus.CANCELLED, error="cancelled before a restart"
                )
                continue
            self.submit(record)
            resumed.append(record.id)
        return resumed

    def stop(self) -> None:
        """Stop at server shutdown: running jobs are killed and keep their rows as they are
        (queued or running), so that the next start resumes them."""
        with self._lock:
            self._stopping = True
            executor = self.executor
        if self.executor_factory is not None:  # ours: stop it; a caller's is the caller's
            stop_executor(executor)

    def _replace(self, broken: Executor) -> bool:
        """Start a new pool in place of ``broken`` (once per broken pool); False if none."""
        with self._lock:
            if self.executor is not broken:
                return True  # another thread replaced it already
            if self._stopping or self.executor_factory is None:
                self._broken = broken
                return False
            logger.error("worker pool broken (a worker died); starting a new one")
            stop_executor(broken)
            self.executor = self.executor_factory()
            self._broken = None
            self.replaced_pools += 1
            return True

    def _finished(self, spec: JobSpec, executor: Executor, future: Future) -> None:
        task_id = spec.task_id
        with self._lock:
            if self._futures.get(task_id, (None,))[0] is future:
                del self._futures[task_id]
            stopping = self._stopping
        if future.cancelled() or stopping:
            return
        failure = future.exception()
        try:
            if isinstance(failure, BrokenExecutor):
                self._worker_died(task_id, executor)
            elif failure is not None:  # the job could not start (unpicklable), or its
                # workers kept dying (Dask's KilledWorker)
                error = f"worker failed: {type(failure).__name__}: {failure}"
                self._record(task_id, _Final(spec.attempt, TaskStatus.FAILED, None, error))
            else:
                self._write_returned(spec, future.result())
            record = self.store.get(task_id)
        except SQLAlchemyError as refused:  # a callback's error would only be logged
            logger.error("task %s: not recorded: %s", task_id, database_reason(refused))
            return
        if record and record.result:
            seconds = record.result.get("planner_statistics", {}).get("time")
            if seconds is not None:
                self.metrics.planning_seconds.observe(seconds)

    def _write_returned(self, spec: JobSpec, outcome: JobOutcome) -> None:
        """A job returned its outcome unwritten: its artifacts (a job without a directory),
        then its status."""
        if outcome.written:
            return
        status, result, error = outcome.status, outcome.result, outcome.error
        task_dir = self.task_dir(spec.task_id).resolve()
        try:
            for name, data in (outcome.files or {}).items():
                path = (task_dir / name).resolve()
                if not path.is_relative_to(task_dir):  # a worker's name cannot point elsewhere
                    raise OSError(f"artifact {name!r} would be outside the task's directory")
                path.parent.mkdir(parents=True, exist_ok=True)
                path.write_bytes(data)
        except OSError as failure:
            logger.error("task %s: artifacts not stored: %s", spec.task_id, failure)
            status, result, error = TaskStatus.FAILED, None, f"artifacts not stored: {failure}"
        self._record(spec.task_id, _Final(spec.attempt, status, result, error))

    def _worker_died(self, task_id: str, broken: Executor) -> None:
        """A job of the broken pool ``broken``: the one that was running fails with the
        reason, one that never started is queued again on a new pool."""
        replaced = self._replace(broken)
        record = self.store.get(task_id)
        if record is None or record.status.finished:
            return
        if record.status is not TaskStatus.QUEUED:
            self._record(task_id, _Final(record.attempt, TaskStatus.FAILED, None, WORKER_DIED))
            return
        if not replaced:
            broke = "the worker pool broke (a worker died)"
            self._record(task_id, _Final(record.attempt, TaskStatus.FAILED, None, broke))
            return
        again = self.store.update(task_id, attempt=record.attempt + 1)
        if again is not None:
            try:
                self.submit(again)
            except ServiceBusyError:
                logger.error("task %s could not be queued again", task_id)
