"""/v1/statics: the statics of configurations, for quick what-ifs."""

from __future__ import annotations

from fastapi import APIRouter

from flycrane.errors import SystemSpecError
from flycrane.model.cable_system import CableSystem
from flycrane.model.statics import evaluate_statics
from flycrane.model.statics_summary import statics_summary
from flycrane.model.system_spec import system_preset
from service.deps import READ
from service.errors import error_responses
from service.schemas import StaticsCreate

router = APIRouter(prefix="/v1/statics", tags=["statics"])


@router.post("", dependencies=READ, responses=error_responses(401, 413))
def statics(body: StaticsCreate) -> dict:
    """Tensions, tension ranges, thrusts, margins, cost and violated constraints of each q."""
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
