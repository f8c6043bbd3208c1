"""How far each drone may be from where it is told: the position-error model a plan's
obstacle clearance follows from (design.md section 9: clearance must come from a stated
model, never from an assumption of perfect tracking).

Errors are bounds [m] (what a flight is judged against), horizontal and vertical, of two
kinds:

- **common**: all three drones off by about the same (GNSS and barometric drift, a shared
  estimate bias): the load moves with them, so the obstacles must be this far away;
- **relative**: how far the drones may be off *from each other* (independent estimate and
  tracking errors): the load shifts and turns, by about as much at the platform.

Each model also names the positioning it holds with (``height_source``, ``min_fix_type``):
the exported ``.parm`` sets the height source (:func:`missions.autopilots.ardupilot.
team_parameters`) and the release is refused when a vehicle reports otherwise
(:mod:`missions.execution.readiness`). A barometer's height drifts by decimetres within a
flight (SITL's uncalibrated ones read 4-5 % of the height high), more than any of the
centimetre bounds below.

The obstacle clearance is ``max(common) + max(relative)``: the load's worst displacement
when the common error and the relative one point the same way. Payload points far from the
platform move more when the platform turns; the flight report measures the clearance a
flight kept, which is how the presets below were checked.

Presets (:data:`PRESETS`):

- ``sitl``: ArduCopter 4.5.7 SITL with GNSS height: the bounds its Rescue and Puzzle
  flights kept, estimate against truth and between the drones (BENCHMARKS.md, "Moved from
  code comments"); GNSS height, a 3-D fix;
- ``rtk``: an RTK GNSS fix (receiver specifications: about 1-2 cm horizontal, 2-3 cm
  vertical) plus a copter's tracking of a slow path, a few centimetres: a stated
  assumption, not measured here; GNSS height, an RTK fixed solution (fix type 6);
- ``gnss``: plain GNSS and barometer: metres (receiver specifications and ArduPilot's
  documentation on barometer drift): a stated assumption; no scene of ours can be planned
  with it, which is the point: a cable-suspended load near obstacles needs RTK; any
  height source, a 3-D fix;
- ``exact``: no error (for simulations that track perfectly, e.g. tests of the planner);
  no positioning named.
"""

from __future__ import annotations

from typing import Literal

from pydantic import BaseModel, ConfigDict, Field


class PositionErrorModel(BaseModel):
    """Bounds on the drones' position errors [m] (module docstring)."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    common_horizontal: float = Field(
        ge=0, le=100, description="[m] shared by all drones", strict=True
    )
    common_vertical: float = Field(
        ge=0, le=100, description="[m] shared by all drones", strict=True
    )
    relative_horizontal: float = Field(
        ge=0, le=100, description="[m] between two drones", strict=True
    )
    relative_vertical: float = Field(
        ge=0, le=100, description="[m] between two drones", strict=True
    )
    height_source: Literal["gnss", "barometer", "any"] = Field(
        "gnss", description="where each drone's height must come from (EK3_SRC1_POSZ)"
    )
    min_fix_type: int = Field(
        3, ge=0, le=6, strict=True, description="least GNSS fix (GPS_RAW_INT fix_type)"
    )

    @property
    def own(self) -> tuple[float, float]:
        """Each drone's own error about the three's mean [m] (horizontal radius, vertical
        half-height): three errors pairwise within r are each within 2r/3 of their mean."""
        return 2 / 3 * self.relative_horizontal, 2 / 3 * self.relative_vertical

    @property
    def obstacle_clearance(self) -> float:
        """The least distance the plan keeps from every obstacle [m] (module docstring)."""
        common = max(self.common_horizontal, self.common_vertical)
        return common + max(self.relative_horizontal, self.relative_vertical)


PRESETS: dict[str, PositionErrorModel] = {
    "sitl": PositionErrorModel(
        common_horizontal=0.04, common_vertical=0.04, relative_horizontal=0.03,
        relative_vertical=0.02, height_source="gnss", min_fix_type=3,
    ),
    "rtk": PositionErrorModel(
        common_horizontal=0.03, common_vertical=0.05, relative_horizontal=0.02,
        relative_vertical=0.03, height_source="gnss", min_fix_type=6,
    ),
    "gnss": PositionErrorModel(
        common_horizontal=1.5, common_vertical=3.0, relative_horizontal=0.5,
        relative_vertical=0.5, height_source="any", min_fix_type=3,
    ),
    "exact": PositionErrorModel(
        common_horizontal=0.0, common_vertical=0.0, relative_horizontal=0.0,
        relative_vertical=0.0, height_source="any", min_fix_type=0,
    ),
}  # fmt: skip


def position_error_model(value: str | PositionErrorModel) -> PositionErrorModel:
    """The model of a preset name, or the model itself.

    Raises
    ------
    KeyError
        For an unknown preset name (:class:`MissionOptions` validates names first).
    """
    return PRESETS[value] if isinstance(value, str) else value
