"""Service errors and the one place that maps domain errors to HTTP responses.

Every refusal names the field or the object and the reason, in FastAPI's own error shape
(``{"detail": [{"loc": [...], "msg": ..., "type": ...}]}`` for 422) or ``{"detail": msg}``.
"""

from __future__ import annotations

from fastapi import FastAPI, Request
from fastapi.encoders import jsonable_encoder
from fastapi.exceptions import RequestValidationError
from fastapi.responses import JSONResponse

from flycrane.errors import FlyCraneError, InputError


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


#: Error types of a union branch the input plainly did not mean (a dict given where the
#: other branch wanted a string or a list, or the other way round).
_WRONG_BRANCH = {
    dict: {"string_type", "list_type", "tuple_type"},
    list: {"model_type", "dict_type", "model_attributes_type", "string_type"},
}


def _readable_location(loc: tuple) -> list:
    """Drop pydantic's union-branch and validator tags from an error location."""
    return [
        part
        for part in loc
        if isinstance(part, int)
        or not (
            part in ("str", "int", "float")
            or "[" in part
            or part.startswith("function-")
            or part[:1].isupper()
            or part in ("octahedral", "generic", "box", "cylinder", "sphere", "mesh")
        )
    ]


def clean_validation_errors(errors: list[dict]) -> list[dict]:
    """Schema errors with readable locations and without wrong-branch noise."""
    cleaned, seen = [], set()
    for error in errors:
        kind = next((k for k in _WRONG_BRANCH if isinstance(error.get("input"), k)), None)
        if kind is not None and error["type"] in _WRONG_BRANCH[kind]:
            continue
        loc = _readable_location(tuple(error["loc"]))
        key = (tuple(loc), error["msg"])
        if key not in seen:
            seen.add(key)
            cleaned.append({"loc": loc, "msg": error["msg"], "type": error["type"]})
    return cleaned or [{"loc": list(e["loc"]), "msg": e["msg"], "type": e["type"]} for e in errors]


def install_error_handlers(app: FastAPI) -> None:
    """Map domain errors to responses (registered once by ``create_app``)."""

    @app.exception_handler(ServiceError)
    async def _service_error(_request: Request, error: ServiceError) -> JSONResponse:
        return JSONResponse(
            {"detail": str(error)}, status_code=error.status_code, headers=error.headers
        )

    @app.exception_handler(RequestValidationError)
    async def _schema_error(_request: Request, error: RequestValidationError) -> JSONResponse:
        body = {"detail": clean_validation_errors(jsonable_encoder(error.errors()))}
        return JSONResponse(body, status_code=422)

    @app.exception_handler(InputError)
    async def _input_error(_request: Request, error: InputError) -> JSONResponse:
        return JSONResponse(input_error_body(error), status_code=422)
