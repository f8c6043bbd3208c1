"""The FastAPI application: routers, error handlers, request limits, lifespan.

``create_app(settings, executor)`` builds one application; its lifespan locks the data
directory and opens the database, both checked (:mod:`service.startup`: a full disk, a
corrupt or read-only database refuse the start in one line), starts the job manager (a
local process pool unless an executor is given), resumes the tasks a previous run left
queued or running, deletes finished tasks past their retention (at start and hourly),
writes again the task outcomes the database refused (every few seconds,
:meth:`JobManager.reconcile`), and at exit stops the pool, killing running jobs (their rows
stay as they were, for the next start to resume).
"""

from __future__ import annotations

import asyncio
import logging
from collections.abc import AsyncIterator
from concurrent.futures import Executor, ThreadPoolExecutor
from contextlib import asynccontextmanager, suppress

from fastapi import FastAPI
from fastapi.concurrency import run_in_threadpool

from flycrane.execution import executor_for
from service.api.routes import docs, health, presets, statics, tasks, view
from service.deps import READ, ServiceState
from service.errors import ErrorBody, error_responses, install_error_handlers
from service.jobs import JobManager
from service.lifecycle import RETENTION_INTERVAL, purge_expired
from service.limits import Slots
from service.metrics import ServiceMetrics
from service.middleware import BodySizeLimit, JsonBodiesOnly, SecurityHeaders, TrustedHosts
from service.settings import Settings, get_settings
from service.startup import open_storage
from service.storage import TaskStore
from service.uploads import UploadRunner

logger = logging.getLogger(__name__)

#: Retry-After of a what-if refused because others are computed [s]: they are short (at
#: most 1000 configurations each).
STATICS_RETRY_AFTER = 1


async def _sweep(state: ServiceState) -> None:
    """Delete expired tasks every RETENTION_INTERVAL seconds (the first sweep ran at start)."""
    while True:
        await asyncio.sleep(RETENTION_INTERVAL)
        try:
            settings = state.settings
            await run_in_threadpool(
                purge_expired, state.store, settings.tasks_dir, settings.retention_days
            )
        except Exception:  # a busy database: try again next time
            logger.exception("retention sweep failed")


async def _reconcile(state: ServiceState) -> None:
    """Write the task outcomes the database refused, every ``reconcile_interval`` seconds
    (a full disk: :meth:`JobManager.reconcile`)."""
    while True:
        await asyncio.sleep(state.jobs.reconcile_interval)
        try:
            await run_in_threadpool(state.jobs.reconcile)
        except Exception:
            logger.exception("reconciling task outcomes failed")


def create_app(settings: Settings | None = None, executor: Executor | None = None) -> FastAPI:
    """One application instance (tests pass their own settings and executor)."""
    settings = settings or get_settings()

    @asynccontextmanager
    async def lifespan(app: FastAPI) -> AsyncIterator[None]:
        lock, engine = open_storage(settings)  # checked, migrated before any worker opens it
        url = settings.resolved_database_url
        store = TaskStore(engine)
        metrics = ServiceMetrics(store)

        def ours() -> Executor:
            return executor_for(settings.dask_scheduler, settings.workers)

        jobs = JobManager(
            store,
            executor or ours(),
            url,
            settings.tasks_dir,
            settings.max_queued_tasks,
            metrics,
            executor_factory=None if executor else ours,
            shared_disk=settings.dask_scheduler is None,
        )
        uploads = UploadRunner(settings.max_concurrent_uploads, settings.upload_timeout)
        what_ifs = Slots(settings.max_concurrent_statics, "statics requests", STATICS_RETRY_AFTER)
        health_thread = ThreadPoolExecutor(max_workers=1, thread_name_prefix="health")
        state = ServiceState(settings, store, jobs, metrics, uploads, what_ifs, health_thread)
        app.state.service = state
        purge_expired(store, settings.tasks_dir, settings.retention_days)
        resumed = jobs.resume_unfinished()
        if resumed:
            logger.info("resumed %d unfinished tasks", len(resumed))
        timers = [asyncio.create_task(_sweep(state)), asyncio.create_task(_reconcile(state))]
        try:
            yield
        finally:
            for timer in timers:
                timer.cancel()
                with suppress(asyncio.CancelledError):
                    await timer
            uploads.stop()
            health_thread.shutdown(wait=False)
            jobs.stop()
            store.engine.dispose()
            lock.release()

    app = FastAPI(
        title="FlyCrane mission service",
        version="1.0.0",
        description="Plans 6-D manipulation with a three-drone aerial crane (bidirectional "
        "T-RRT over cable statics) and exports synchronized MAVLink missions, MCAP logs and "
        "plots.",
        lifespan=lifespan,
        responses={
            **error_responses(400),
            415: {
                "model": ErrorBody,
                "description": "a POST without Content-Type: application/json",
            },
        },
        # Our own /docs (vendored Swagger UI, no CDN); no /redoc, which loads from one.
        openapi_url="/openapi.json" if settings.api_docs else None,
        docs_url=None,
        redoc_url=None,
    )
    install_error_handlers(app)
    for module in (tasks, statics, presets, health):
        app.include_router(module.router)
    app.include_router(
        view.router,
        dependencies=READ,
        responses=error_responses(401, 404, 409, 503),
    )
    # What carries no task data is open, as the API's description is: the viewer's files
    # and the docs.
    app.include_router(view.static_router)
    if settings.api_docs:
        app.include_router(docs.router)
    app.add_middleware(JsonBodiesOnly)
    app.add_middleware(BodySizeLimit, limit=settings.max_request_bytes)
    # A request for another host name is refused before anything else runs ...
    app.add_middleware(
        TrustedHosts,
        allowed_hosts=settings.host_patterns,
        health_hosts=settings.health_host_patterns,
    )
    # ... and every answer, that refusal included, carries the security headers.
    app.add_middleware(SecurityHeaders)
    return app
