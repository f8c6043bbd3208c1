"""Service errors and the one place that maps domain errors to HTTP responses.

Every refusal names the field or the object and the reason, in FastAPI's own error shape
(``{"detail": [{"loc": [...], "msg": ..., "type": ...}]}`` for 422) or ``{"detail": msg}``.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

from fastapi import FastAPI, Request
from fastapi.encoders import jsonable_encoder
from fastapi.exceptions import RequestValidationError
from fastapi.responses import JSONResponse
from pydantic import BaseModel
from sqlalchemy.exc import OperationalError, SQLAlchemyError
from sqlalchemy.exc import TimeoutError as PoolTimeoutError

from flycrane.errors import FieldProblem, FlyCraneError, InputError, readable_errors
from flycrane.planning.validity import InvalidConfigurationError, InvalidReason
from service.storage import database_reason


class ServiceError(FlyCraneError):
    """Root of the errors the service raises on purpose; ``status_code`` is the HTTP code."""

    status_code = 500

    def __init__(self, message: str, headers: dict[str, str] | None = None) -> None:
        super().__init__(message)
        self.headers = headers


class TaskNotFoundError(ServiceError):
    status_code = 404


class TaskNotReadyError(ServiceError):
    """An artifact or an upload asked of a task that is not done."""

    status_code = 409


class ArtifactNotFoundError(ServiceError):
    status_code = 404


class ServiceBusyError(ServiceError):
    """The queue is full; the client should retry later (503 with Retry-After)."""

    status_code = 503


class UploadNotAllowedError(ServiceError):
    """A vehicle address outside the configured allow-list (403)."""

    status_code = 403


class SameVehicleError(InputError):
    """Addresses of an upload that reach one vehicle (the same MAVLink system id in their
    heartbeats): refused before anything is sent (422, each later address as
    ``vehicles[k]``).

    Attributes
    ----------
    addresses : tuple[str, ...]
        The upload's addresses, drone 1 first.
    repeats : tuple[tuple[int, int, int], ...]
        ``(k, first, system_id)``: ``addresses[k]`` reaches the system ``addresses[first]``
        reaches.
    """

    def __init__(self, addresses: Sequence[str], repeats: Sequence[tuple[int, int, int]]) -> None:
        self.addresses, self.repeats = tuple(addresses), tuple(repeats)
        super().__init__(
            [
                FieldProblem(
                    f"vehicles[{k}]",
                    f"{addresses[k]} reaches the same vehicle as vehicles[{first}] "
                    f"({addresses[first]}): system id {system} answers on both; each drone "
                    "needs its own vehicle, with its own system id (SYSID_THISMAV)",
                )
                for k, first, system in repeats
            ]
        )


class UnauthorizedError(ServiceError):
    status_code = 401


class ArtifactUnreadableError(ServiceError):
    """A task's artifact exists but cannot be used (corrupt or truncated on disk)."""

    status_code = 409


class DataDirLockedError(ServiceError):
    """Another server process holds the data directory (two would run each other's tasks)."""

    status_code = 503


class StartupError(ServiceError):
    """The server cannot start on its storage: the data directory or the database is unusable
    (one line naming the file and the reason; ``flycrane serve`` prints it and exits 1)."""

    status_code = 503


#: Problems a 422 lists; the others are counted (a request of many small mistakes must not
#: make the server answer many times its size: issue 22, item 6).
MAX_LISTED_PROBLEMS = 20

#: Retry-After for a busy or unreachable database [s].
DATABASE_RETRY_AFTER = 5


class ErrorBody(BaseModel):
    """Every error but 422: ``{"detail": "what was wrong"}``."""

    detail: str


_DESCRIPTIONS = {
    400: "Host header not among the allowed hosts (text), or a body that is not UTF-8 (JSON)",
    401: "a bearer token is required (FLYCRANE_API_TOKEN / FLYCRANE_READ_TOKEN)",
    403: "not allowed (a vehicle address outside the upload allow-list)",
    404: "no such task or artifact",
    409: "the task is not in a state that allows this, or its files are unusable",
    413: "request body larger than FLYCRANE_MAX_REQUEST_BYTES",
    503: "busy: queue full, database locked or no worker pool; see Retry-After",
}


def error_responses(*codes: int) -> dict[int | str, dict[str, Any]]:
    """OpenAPI entries for the error statuses a route can answer with."""
    # JSON whatever the route's own media type (an HTML page's 404 is JSON too).
    json_body = {"application/json": {"schema": ErrorBody.model_json_schema()}}
    responses: dict[int | str, dict[str, Any]] = {}
    for code in codes:
        content = dict(json_body)
        if code == 400:  # starlette's TrustedHostMiddleware answers in plain text
            content["text/plain"] = {"schema": {"type": "string"}}
        responses[code] = {"description": _DESCRIPTIONS[code], "content": content}
    return responses


def listed(details: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """The first :data:`MAX_LISTED_PROBLEMS` entries of a 422's ``detail``, and one more
    counting the others (FastAPI's entry shape, type ``too_many_problems``)."""
    if len(details) <= MAX_LISTED_PROBLEMS:
        return details
    more = len(details) - MAX_LISTED_PROBLEMS
    summary = {
        "loc": ["body"],
        "msg": f"and {more} more ({len(details)} in all); the first {MAX_LISTED_PROBLEMS} "
        "are listed",
        "type": "too_many_problems",
    }
    return [*details[:MAX_LISTED_PROBLEMS], summary]


def listed_reasons(reason: InvalidReason) -> str:
    """Why a configuration is invalid, as :class:`InvalidReason` says it, the first
    :data:`MAX_LISTED_PROBLEMS` reasons listed and the others counted."""
    parts = [f"outside the bounds: {b}" for b in reason.out_of_bounds]
    parts += [str(v) for v in reason.violations] + [str(c) for c in reason.contacts]
    if len(parts) <= MAX_LISTED_PROBLEMS:
        return str(reason)
    more = len(parts) - MAX_LISTED_PROBLEMS
    return "; ".join(parts[:MAX_LISTED_PROBLEMS]) + f"; and {more} more ({len(parts)} in all)"


def input_error_body(error: InputError) -> dict:
    """FastAPI's 422 body for field problems found after schema validation."""
    return {
        "detail": listed(
            [
                {"loc": ["body", *p.field.split(".")], "msg": p.reason, "type": "value_error"}
                for p in error.problems
            ]
        )
    }


def install_error_handlers(app: FastAPI) -> None:
    """Map domain errors to responses (registered once by ``create_app``)."""

    @app.exception_handler(ServiceError)
    async def _service_error(_request: Request, error: ServiceError) -> JSONResponse:
        return JSONResponse(
            {"detail": str(error)}, status_code=error.status_code, headers=error.headers
        )

    @app.exception_handler(RequestValidationError)
    async def _schema_error(_request: Request, error: RequestValidationError) -> JSONResponse:
        body = {"detail": listed(readable_errors(jsonable_encoder(error.errors())))}
        return JSONResponse(body, status_code=422)

    @app.exception_handler(InputError)
    async def _input_error(_request: Request, error: InputError) -> JSONResponse:
        return JSONResponse(input_error_body(error), status_code=422)

    @app.exception_handler(InvalidConfigurationError)
    async def _invalid_configuration(
        _request: Request, error: InvalidConfigurationError
    ) -> JSONResponse:
        message = listed_reasons(error.reason)
        detail = {"loc": ["body", error.what], "msg": message, "type": "value_error"}
        return JSONResponse({"detail": [detail]}, status_code=422)

    @app.exception_handler(OperationalError)
    @app.exception_handler(PoolTimeoutError)
    async def _database_busy(_request: Request, error: SQLAlchemyError) -> JSONResponse:
        # SQLite's "database is locked" after the busy timeout, a PostgreSQL server gone:
        # the request was fine, the database could not take it now.
        reason = database_reason(error)
        return JSONResponse(
            {"detail": f"the database is busy or unreachable; retry later ({reason})"},
            status_code=503,
            headers={"Retry-After": str(DATABASE_RETRY_AFTER)},
        )
