"""Service errors and the one place that maps domain errors to HTTP responses.

Every refusal names the field or the object and the reason, in FastAPI's own error shape
(``{"detail": [{"loc": [...], "msg": ..., "type": ...}]}`` for 422) or ``{"detail": msg}``.
"""

from __future__ import annotations

from fastapi import FastAPI, Request
from fastapi.encoders import jsonable_encoder
from fastapi.exceptions import RequestValidationError
from fastapi.responses import JSONResponse

from flycrane.errors import FlyCraneError, InputError, readable_errors


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


class UnauthorizedError(ServiceError):
    status_code = 401


def input_error_body(error: InputError) -> dict:
    """FastAPI's 422 body for field problems found after schema validation."""
    return {
        "detail": [
            {"loc": ["body", *p.field.split(".")], "msg": p.reason, "type": "value_error"}
            for p in error.problems
        ]
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
        body = {"detail": readable_errors(jsonable_encoder(error.errors()))}
        return JSONResponse(body, status_code=422)

    @app.exception_handler(InputError)
    async def _input_error(_request: Request, error: InputError) -> JSONResponse:
        return JSONResponse(input_error_body(error), status_code=422)
