"""The FastAPI application: routers, error handlers, request-size limit, lifespan.

``create_app(settings, executor)`` builds one application; its lifespan opens the database,
starts the job manager (a local process pool unless an executor is given), resumes the
tasks a previous run left queued or running, and shuts the pool down at exit.
"""

from __future__ import annotations

import logging
from collections.abc import AsyncIterator
from concurrent.futures import Executor
from contextlib import asynccontextmanager

from fastapi import FastAPI
from starlette.types import ASGIApp, Message, Receive, Scope, Send

from flycrane.execution import local_executor
from service.api.routes import health, presets, statics, tasks, view
from service.deps import ServiceState
from service.errors import install_error_handlers
from service.jobs import JobManager
from service.metrics import ServiceMetrics
from service.settings import Settings, get_settings
from service.storage import TaskStore, make_engine

logger = logging.getLogger(__name__)


class BodySizeLimit:
    """Refuse request bodies above ``limit`` bytes with 413, before they are parsed.

    Counts the bytes as they arrive, so a missing or lying Content-Length does not help.
    """

    def __init__(self, app: ASGIApp, limit: int) -> None:
        self.app, self.limit = app, limit

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return
        declared = dict(scope.get("headers", [])).get(b"content-length")
        if declared is not None and declared.isdigit() and int(declared) > self.limit:
            await self._refuse(send)
            return
        seen = 0

        async def counting() -> Message:
            nonlocal seen
            message = await receive()
            seen += len(message.get("body", b""))
            if seen > self.limit:
                raise _TooLarge
            return message

        try:
            await self.app(scope, counting, send)
        except _TooLarge:
            await self._refuse(send)

    async def _refuse(self, send: Send) -> None:
        body = f'{{"detail": "request body larger than {self.limit} bytes"}}'.encode()
        await send(
            {
                "type": "http.response.start",
                "status": 413,
                "headers": [(b"content-type", b"application/json")],
            }
        )
        await send({"type": "http.response.body", "body": body})


class _TooLarge(Exception):
    pass


def create_app(settings: Settings | None = None, executor: Executor | None = None) -> FastAPI:
    """One application instance (tests pass their own settings and executor)."""
    settings = settings or get_settings()

    @asynccontextmanager
    async def lifespan(app: FastAPI) -> AsyncIterator[None]:
        settings.tasks_dir.mkdir(parents=True, exist_ok=True)
        url = settings.resolved_database_url
        store = TaskStore(make_engine(url))
        metrics = ServiceMetrics(store)
        pool = executor or local_executor(settings.workers)
        jobs = JobManager(store, pool, url, settings.tasks_dir, settings.max_queued_tasks, metrics)
        app.state.service = ServiceState(settings, store, jobs, metrics)
        resumed = jobs.resume_unfinished()
        if resumed:
            logger.info("resumed %d unfinished tasks", len(resumed))
        try:
            yield
        finally:
            if executor is None:  # ours: stop it; a caller's executor is the caller's
                pool.shutdown(wait=False, cancel_futures=True)
            store.engine.dispose()

    app = FastAPI(
        title="FlyCrane mission service",
        version="1.0.0",
        description="Plans 6-D manipulation with a three-drone aerial crane (T-RRT over "
        "cable statics) and exports synchronized MAVLink missions, MCAP logs and plots.",
        lifespan=lifespan,
    )
    install_error_handlers(app)
    for module in (tasks, view, statics, presets, health):
        app.include_router(module.router)
    app.add_middleware(BodySizeLimit, limit=settings.max_request_bytes)
    return app
