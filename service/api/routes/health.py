"""Liveness and Prometheus metrics."""

from __future__ import annotations

import asyncio

from fastapi import APIRouter, Response
from fastapi.responses import JSONResponse
from prometheus_client import CONTENT_TYPE_LATEST, generate_latest
from sqlalchemy import text
from sqlalchemy.exc import SQLAlchemyError

from service.deps import ServiceState, StateDep
from service.schemas import Health

router = APIRouter(tags=["health"])


@router.get(
    "/healthz",
    response_model=Health,
    responses={503: {"model": Health, "description": "the service cannot run tasks now"}},
)
async def healthz(state: StateDep) -> Health | JSONResponse:
    """Whether the service can take and run tasks: its database answers and records what
    tasks do (a full disk refuses it), and its worker pool works (a pool broken by a dead
    worker is replaced; one that cannot be is reported)."""
    # On a thread of its own (the database is asked), not on one of the request threads:
    # it answers while busy requests hold all of them.
    return await asyncio.wrap_future(state.health.submit(_health, state))


def _health(state: ServiceState) -> Health | JSONResponse:
    problems = []
    if not state.jobs.healthy:
        problems.append("no usable worker pool")
    problems += state.jobs.problems  # outcomes the database refused to record (disk full)
    try:
        with state.store.engine.connect() as connection:
            connection.execute(text("SELECT 1"))
    except SQLAlchemyError as error:
        problems.append(f"database unreachable: {type(error).__name__}")
    health = Health(
        status="unavailable" if problems else "ok",
        problems=problems,
        tasks_in_flight=state.jobs.in_flight,
        workers=state.settings.workers,
        replaced_pools=state.jobs.replaced_pools,
    )
    if problems:
        return JSONResponse(health.model_dump(), status_code=503)
    return health


@router.get(
    "/metrics",
    response_class=Response,
    responses={
        200: {"content": {CONTENT_TYPE_LATEST.split(";")[0]: {"schema": {"type": "string"}}}}
    },
)
def metrics(state: StateDep) -> Response:
    """Prometheus text format: tasks per status, planning times, submissions."""
    return Response(generate_latest(state.metrics.registry), media_type=CONTENT_TYPE_LATEST)
