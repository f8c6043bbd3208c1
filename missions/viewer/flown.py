"""Flown drone positions (the optional artifact ``flown.json``) and the load they carried.

A flight report, when a task has one, puts the three drones' flown positions beside the
task's artifacts as ``flown.json`` (docs/viewer.md, "Flown data")::

    {"source": "sitl-true",
     "time": [0.0, 0.1, ...],
     "drones_enu": [[[x1, y1, z1], [x2, y2, z2], [x3, y3, z3]], ...]}

``time`` [s] counts from the planned track's time 0 (mission start, the drones at their first
timed waypoint); ``drones_enu`` [m] are in the task's local ENU frame (its mission origin),
drone 1 first. ``source`` says where they come from (``"sitl-true"``: the simulator's true
positions; ``"sitl-estimate"`` or ``"telemetry"``: the autopilots' estimates). Other keys are
ignored, so a report may carry more.

The platform is not measured: it is reconstructed from the three drones with the direct
kinematics (:mod:`flycrane.model.direct_kinematics`), which also says where that fails.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray
from pydantic import BaseModel, ConfigDict, Field, ValidationError, model_validator

from flycrane.errors import FieldProblem, InputError
from flycrane.model.cable_system import CableSystem
from flycrane.model.direct_kinematics import configuration_from_drone_positions
from flycrane.model.system_spec import problems_from_validation_error
from flycrane.quantities import MAX_LENGTH

#: The file a flight report leaves beside a task's artifacts.
FLOWN_FILE = "flown.json"


class FlownTrackError(InputError):
    """``flown.json`` is unreadable or not of the documented shape; names the field."""


class FlownTrack(BaseModel):
    """Flown drone positions over time (module docstring)."""

    model_config = ConfigDict(frozen=True, extra="ignore")

    source: str = Field(min_length=1, max_length=100, description='e.g. "sitl-true"')
    time: list[float] = Field(min_length=2, description="[s] from the planned time 0")
    drones_enu: list[list[list[float]]] = Field(description="(M, 3, 3) [m], local ENU")

    @model_validator(mode="after")
    def _shapes(self) -> FlownTrack:
        time, drones = np.asarray(self.time), np.asarray(self.drones_enu, dtype=object)
        if drones.shape != (len(time), 3, 3):
            raise ValueError(
                f"drones_enu must have shape (len(time), 3, 3) = ({len(time)}, 3, 3), "
                f"got {drones.shape}"
            )
        if not np.all(np.isfinite(time)) or not np.all(np.isfinite(drones.astype(float))):
            raise ValueError("time and drones_enu must be finite numbers")
        if np.any(np.abs(drones.astype(float)) > MAX_LENGTH):
            raise ValueError(f"drones_enu must be within {MAX_LENGTH:g} m of the task's origin")
        backwards = np.flatnonzero(np.diff(time) < 0)
        if len(backwards):
            k = int(backwards[0]) + 1
            raise ValueError(f"time must not decrease: time[{k}] = {time[k]} < time[{k - 1}]")
        return self

    @property
    def drones(self) -> NDArray[np.float64]:
        return np.asarray(self.drones_enu, dtype=float)


def load_flown(task_dir: Path) -> FlownTrack | None:
    """The task's ``flown.json``, or None where it has none.

    Raises
    ------
    FlownTrackError
        The file is not JSON or not of the documented shape.
    """
    path = Path(task_dir) / FLOWN_FILE
    if not path.exists():
        return None
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
        return FlownTrack.model_validate(data)
    except (OSError, ValueError) as error:
        problems = (
            problems_from_validation_error(error)
            if isinstance(error, ValidationError)
            else [FieldProblem("file", str(error))]
        )
        raise FlownTrackError(problems, FLOWN_FILE) from None


@dataclass(frozen=True)
class FlownLoad:
    """The load reconstructed at M flown samples."""

    time: NDArray[np.float64]  #: (M,) [s]
    drones: NDArray[np.float64]  #: (M, 3, 3) flown drone positions [m]
    q: NDArray[np.float64]  #: (M, 9) reconstructed configurations
    converged: NDArray[np.bool_]  #: (M,) the six cable lengths are met (a pose exists)


def reconstruct(system: CableSystem, flown: FlownTrack, samples: NDArray[np.int64]) -> FlownLoad:
    """Reconstruct the platform at the flown samples ``samples`` (indices into ``time``).

    Every sample starts from the rigid fit of the drone triangle (the hanging branch), not
    from the planned configuration: a flight runs late or early, so the plan at the same
    time can be far from where the load is.
    """
    drones = flown.drones[samples]
    result = configuration_from_drone_positions(system, drones)
    return FlownLoad(np.asarray(flown.time)[samples], drones, result.q, result.converged)
