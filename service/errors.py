"""Service errors and the one place that maps domain errors to HTTP responses.

Every refusal names the field or the object and the reason, in FastAPI's own error shape
(``{"detail": [{"loc": [...], "msg": ..., "type": ...}]}`` for 422) or ``{"detail": msg}``.
"""

from __future__ import annotations

import json
from collections.abc import Mapping, Sequence
from itertools import chain, islice
from typing import Any

from fastapi import FastAPI, Request
from fastapi.encoders import jsonable_encoder
from fastapi.exceptions import RequestValidationError
from fastapi.responses import JSONResponse
from pydantic import BaseModel, ValidationError
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


class InvalidBodyError(ServiceError):
    """A request body its schema refuses (422): ``detail`` is the answer's, made where the
    body was validated, off the event loop (:func:`schema_detail` of :func:`first_errors`)."""

    status_code = 422

    def __init__(self, error: ValidationError) -> None:
        count = error.error_count()
        self.detail = schema_detail(first_errors(error, READ_PROBLEMS), ("body",), count)
        super().__init__(f"the request body has {count} problem(s)")


class StartupError(ServiceError):
    """The server cannot start on its storage: the data directory or the database is unusable
    (one line naming the file and the reason; ``flycrane serve`` prints it and exits 1)."""

    status_code = 503


#: Problems a 422 lists; the others are counted (a request of many small mistakes must not
#: make the server answer many times its size: issue 22, item 6).
MAX_LISTED_PROBLEMS = 20

#: Schema errors made readable for a 422: enough to list MAX_LISTED_PROBLEMS once those of a
#: union's branches the input plainly did not mean are dropped; the others are only counted.
READ_PROBLEMS = 5 * MAX_LISTED_PROBLEMS

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
    503: "busy: queue full, as many uploads or what-ifs running as allowed, database locked "
    "or no worker pool; see Retry-After",
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


def listed(details: list[dict[str, Any]], total: int | None = None) -> list[dict[str, Any]]:
    """The first :data:`MAX_LISTED_PROBLEMS` entries of a 422's ``detail``, and one more
    counting the others (FastAPI's entry shape, type ``too_many_problems``); ``total`` is how
    many problems there are in all when ``details`` holds only the first of them."""
    total = len(details) if total is None else total
    if total <= MAX_LISTED_PROBLEMS:
        return details
    shown = details[:MAX_LISTED_PROBLEMS]
    summary = {
        "loc": ["body"],
        "msg": f"and {total - len(shown)} more ({total} in all); the first {len(shown)} are listed",
        "type": "too_many_problems",
    }
    return [*shown, summary]


def schema_detail(
    errors: Sequence[Mapping[str, Any]], prefix: tuple[str, ...] = (), count: int | None = None
) -> list[dict[str, Any]]:
    """A 422's ``detail`` for pydantic's ``errors`` (``prefix`` before each location, as
    FastAPI writes them): the first ones made readable (:func:`readable_errors`), the others
    counted (:func:`listed`); ``count`` is how many errors there are when ``errors`` holds
    only the first of them.

    Only the first :data:`READ_PROBLEMS` errors are made readable, so that a body of half a
    million wrong items costs no more here than one of twenty; the errors past them are
    counted as pydantic reports them.
    """
    count = len(errors) if count is None else count
    head = [{**e, "loc": (*prefix, *e["loc"])} for e in errors[:READ_PROBLEMS]]
    readable = readable_errors(head)
    total = len(readable) + count - len(head)
    return jsonable_encoder(listed(readable, total))


#: What may come between the entries of a JSON array.
_SEPARATORS = frozenset(", \t\n\r")


def first_errors(error: ValidationError, count: int) -> list[dict[str, Any]]:
    """The first ``count`` entries of ``error.errors()`` (without URL and context), the
    others not made.

    ``errors()`` makes a Python object of every entry, holding the interpreter lock (and the
    event loop with it) for as long as the body has wrong items; pydantic's JSON of them is
    made many times faster, and is read here only as far as needed.
    """
    text = error.json(include_url=False, include_context=False)
    decoder = json.JSONDecoder()
    found: list[dict[str, Any]] = []
    at = 1  # past "["
    while len(found) < count:
        while text[at] in _SEPARATORS:
            at += 1
        if text[at] == "]":
            break
        entry, at = decoder.raw_decode(text, at)
        found.append(entry)
    return found


def listed_reasons(reason: InvalidReason) -> str:
    """Why a configuration is invalid, as :class:`InvalidReason` says it, the first
    :data:`MAX_LISTED_PROBLEMS` reasons listed and the others counted."""
    total = len(reason.out_of_bounds) + len(reason.violations) + len(reason.contacts)
    if total <= MAX_LISTED_PROBLEMS:
        return str(reason)
    parts = chain(
        (f"outside the bounds: {b}" for b in reason.out_of_bounds),
        map(str, reason.violations),
        map(str, reason.contacts),
    )
    first = "; ".join(islice(parts, MAX_LISTED_PROBLEMS))
    return f"{first}; and {total - MAX_LISTED_PROBLEMS} more ({total} in all)"


def input_error_body(error: InputError) -> dict:
    """FastAPI's 422 body for field problems found after schema validation."""
    first = error.problems[:MAX_LISTED_PROBLEMS]
    detail = [
        {"loc": ["body", *p.field.split(".")], "msg": p.reason, "type": "value_error"}
        for p in first
    ]
    return {"detail": listed(detail, len(error.problems))}


def install_error_handlers(app: FastAPI) -> None:
    """Map domain errors to responses (registered once by ``create_app``)."""

    @app.exception_handler(ServiceError)
    async def _service_error(_request: Request, error: ServiceError) -> JSONResponse:
        return JSONResponse(
            {"detail": str(error)}, status_code=error.status_code, headers=error.headers
        )

    @app.exception_handler(RequestValidationError)
    async def _schema_error(_request: Request, error: RequestValidationError) -> JSONResponse:
        return JSONResponse({"detail": schema_detail(error.errors())}, status_code=422)

    @app.exception_handler(InvalidBodyError)
    async def _invalid_body(_request: Request, error: InvalidBodyError) -> JSONResponse:
        return JSONResponse({"detail": error.detail}, status_code=422)

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
