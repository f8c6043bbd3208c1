"""/v1/statics: the statics of configurations, for quick what-ifs.

At most ``FLYCRANE_MAX_CONCURRENT_STATICS`` are computed at once, each on a request thread
(the body validated there too, :data:`service.schemas.StaticsBody`); more are refused at once
with 503 and Retry-After, so that what-ifs cannot take every thread of the server.
"""

from __future__ import annotations

from typing import Any

from fastapi import APIRouter
from fastapi.concurrency import run_in_threadpool

from flycrane.errors import SystemSpecError
from flycrane.model.cable_system import CableSystem
from flycrane.model.statics import evaluate_statics
from flycrane.model.statics_summary import statics_summary
from flycrane.model.system_spec import system_preset
from service.deps import READ, StateDep
from service.errors import error_responses
from service.schemas import StaticsBody, StaticsCreate, validated

router = APIRouter(prefix="/v1/statics", tags=["statics"])


@router.post("", dependencies=READ, responses=error_responses(401, 413, 503))
async def statics(body: StaticsBody, state: StateDep) -> dict:
    """Tensions, tension ranges, thrusts, margins, cost and violated constraints of each q
    (503 while ``FLYCRANE_MAX_CONCURRENT_STATICS`` others are computed)."""
    with state.statics.held():
        return await run_in_threadpool(_statics, body)


def _statics(raw: Any) -> dict:
    body = validated(StaticsCreate, raw)
    spec = system_preset(body.system) if isinstance(body.system, str) else body.system
    try:
        system = CableSystem.from_spec(spec)
    except SystemSpecError as error:
        raise error.under("system") from None
    report = evaluate_statics(system, body.q)
    return {
        "results": [
            statics_summary(system, report, body.cost_form, row) for row in range(len(body.q))
        ]
    }
