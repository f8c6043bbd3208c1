"""Request and response schemas of the HTTP API (``XCreate`` / ``XPublic`` families).

The task body itself is :class:`missions.task.spec.TaskSpec`, shared with ``flycrane plan``.

Request bodies are not validated by FastAPI, which does it on the event loop and makes one
entry per problem there: a body of many wrong items under the size limit (a scene's
obstacles, a mesh's vertices, unknown keys) would hold every request up. The routes take the
parsed JSON (:data:`TaskBody`, :data:`StaticsBody`, :data:`UploadBody`, each documented as
its schema) and call :func:`validated` on a worker thread.
"""

from __future__ import annotations

import math
from datetime import datetime
from typing import Annotated, Any, Literal, TypeVar

from fastapi import Body
from pydantic import BaseModel, ConfigDict, Field, PlainValidator, ValidationError

from flycrane.model.cost import CostForm
from flycrane.model.system_spec import SystemSpec
from flycrane.quantities import Configuration
from missions.task.spec import TaskSpec
from service.errors import InvalidBodyError
from service.storage import TaskRecord, TaskStatus

M = TypeVar("M", bound=BaseModel)


class TaskAccepted(BaseModel):
    id: str
    url: str
    status: TaskStatus


class TaskPublic(BaseModel):
    """A task as the API shows it."""

    id: str
    url: str
    name: str
    status: TaskStatus
    created_at: datetime
    updated_at: datetime
    progress: dict[str, Any] | None = Field(None, description="while queued or running")
    error: str | None = None
    cancel_requested: bool = False
    result: dict[str, Any] | None = Field(
        None, description="planner status and statistics, path metrics, mission summary"
    )
    artifacts: dict[str, str] = Field(default_factory=dict, description="name -> URL")

    @classmethod
    def of(cls, record: TaskRecord, base_url: str) -> TaskPublic:
        """``base_url`` ends with a slash (deps.base_url)."""
        url = f"{base_url}v1/tasks/{record.id}"
        files = (record.result or {}).get("artifacts", {})
        artifacts = {name: f"{url}/artifacts/{name}" for name in files.values()}
        if files:
            artifacts["bundle.zip"] = f"{url}/bundle.zip"
        return cls(
            id=record.id,
            url=url,
            name=record.request.get("name", ""),
            status=record.status,
            created_at=record.created_at,
            updated_at=record.updated_at,
            progress=None if record.status.finished else record.progress,
            error=record.error,
            cancel_requested=record.cancel_requested,
            result=record.result,
            artifacts=artifacts,
        )


class TaskPage(BaseModel):
    items: list[TaskPublic]
    total: int
    offset: int
    limit: int


class StaticsCreate(BaseModel):
    """A what-if: the statics of configurations of a system."""

    model_config = ConfigDict(extra="forbid", allow_inf_nan=False)

    system: str | SystemSpec = "benchmark"
    q: list[Configuration] = Field(min_length=1, max_length=1000)
    cost_form: CostForm = CostForm.NORMALIZED


def _as_parsed(value: Any) -> Any:
    return value


#: The body of POST /v1/tasks as FastAPI hands it over: the parsed JSON, not validated yet
#: (the API's description shows TaskSpec); the route validates it (:func:`validated`).
TaskBody = Annotated[Any, Body(), PlainValidator(_as_parsed, json_schema_input_type=TaskSpec)]
#: The body of POST /v1/statics, likewise (:class:`StaticsCreate`).
StaticsBody = Annotated[
    Any, Body(), PlainValidator(_as_parsed, json_schema_input_type=StaticsCreate)
]


def validated(model: type[M], body: Any) -> M:
    """``body``, a request's parsed JSON, as a ``model``. Call it on a worker thread: pydantic
    makes one entry per problem, however many items of the body are wrong.

    Raises
    ------
    InvalidBodyError
        The model refuses it (422: the first problems listed, the others counted).
    """
    try:
        return model.model_validate(body)
    except ValidationError as error:
        raise InvalidBodyError(error) from None


Address = Annotated[str, Field(min_length=1, max_length=200)]


class UploadCreate(BaseModel):
    """Vehicle connection strings, one per drone (drone 1 first)."""

    model_config = ConfigDict(extra="forbid")

    vehicles: tuple[Address, Address, Address] = Field(
        description='e.g. "udpout:127.0.0.1:14550" or "/dev/ttyACM0:57600"; three different '
        "vehicles, each allowed by FLYCRANE_UPLOAD_NETWORKS or FLYCRANE_UPLOAD_DEVICES"
    )


#: The body of POST /v1/tasks/{id}/upload, likewise (:class:`UploadCreate`).
UploadBody = Annotated[Any, Body(), PlainValidator(_as_parsed, json_schema_input_type=UploadCreate)]


class ParameterDifference(BaseModel):
    """A vehicle parameter that is not what the drone's ``.parm`` says the plan assumes."""

    name: str
    expected: float
    found: float | None = Field(
        description="the vehicle's value; null when it does not answer for it, or answers "
        "with no number (NaN or infinity, which JSON cannot carry: see found_text)"
    )
    found_text: str = Field(
        description="the vehicle's value as text ('250', 'nan', 'inf'), or 'no answer'"
    )

    @classmethod
    def of(cls, name: str, expected: float, found: float | None) -> ParameterDifference:
        finite = found is not None and math.isfinite(found)
        text = "no answer" if found is None else f"{found:g}"
        return cls(name=name, expected=expected, found=found if finite else None, found_text=text)


class VehicleUpload(BaseModel):
    """One vehicle's outcome: its own error, never another vehicle's."""

    drone: int
    vehicle: str
    ok: bool = Field(description="mission uploaded and verified, parameters as planned")
    detail: str
    parameter_differences: list[ParameterDifference] = []


class UploadPublic(BaseModel):
    ok: bool
    vehicles: list[VehicleUpload]


class Health(BaseModel):
    status: Literal["ok", "unavailable"]
    problems: list[str] = Field(default_factory=list, description="why not ok")
    tasks_in_flight: int
    workers: int
    replaced_pools: int = Field(description="worker pools replaced after a worker died")
