"""The FlyCrane system description (design.md sections 4-5): geometry, masses and limits.

:class:`SystemSpec` is the plain-data schema that crosses every boundary (files, HTTP, CLI).
Its defaults are the benchmark system of design.md section 5. The numeric model derived from
it lives in :mod:`flycrane.model.cable_system`.

Numbering follows design.md: cables 1..6, drones 1..3, drone 1 on cables (1, 6), drone 2 on
(2, 3), drone 3 on (4, 5). Lists in a spec are 0-based in Python but every message names
cables and drones 1-based, as users and the paper count them.
"""

from __future__ import annotations

import json
import math
import tomllib
from pathlib import Path
from typing import Annotated, Literal

import numpy as np
import tomli_w
from pydantic import (
    BaseModel,
    BeforeValidator,
    ConfigDict,
    Field,
    ValidationError,
    field_validator,
    model_validator,
)

from flycrane.errors import FieldProblem, InputError, SystemSpecError, dotted, readable_errors
from flycrane.quantities import (
    MAX_FORCE,
    MAX_GRAVITY,
    Force,
    Length,
    Mass,
    NonNegativeForce,
    PerturbationRadius,
    Point,
)
from flycrane.user_files import read_text

#: Cable pairs of each drone, 0-based: drone k hangs from cables DRONE_CABLES[k].
DRONE_CABLES: tuple[tuple[int, int], ...] = ((0, 5), (1, 2), (3, 4))


def _one_for_all(count: int, item: str) -> BeforeValidator:
    """Accept one number for all ``count`` items (drones, cables) as well as a list."""

    def broadcast(value: object) -> object:
        if isinstance(value, int | float) and not isinstance(value, bool):
            return (value,) * count
        if isinstance(value, list | tuple) and len(value) != count:
            raise ValueError(f"expected one number or {count} (one per {item}), got {len(value)}")
        return value

    return BeforeValidator(broadcast)


DroneMasses = Annotated[tuple[Mass, Mass, Mass], _one_for_all(3, "drone")]
DroneForces = Annotated[tuple[Force, Force, Force], _one_for_all(3, "drone")]
CableForces = Annotated[tuple[Force, Force, Force, Force, Force, Force], _one_for_all(6, "cable")]
CableNonNegativeForces = Annotated[
    tuple[
        NonNegativeForce,
        NonNegativeForce,
        NonNegativeForce,
        NonNegativeForce,
        NonNegativeForce,
        NonNegativeForce,
    ],
    _one_for_all(6, "cable"),
]


class _Frozen(BaseModel):
    # Numbers are finite everywhere (flycrane.quantities), and a bool is not a number.
    model_config = ConfigDict(frozen=True, extra="forbid", allow_inf_nan=False)


class OctahedralGeometry(_Frozen):
    """The paper's octahedral FlyCrane: equilateral platform, coupled base points.

    Vertices V1 = (r, 0, 0), V2 = r(cos 120, sin 120, 0), V3 = r(cos 240, sin 240, 0) with
    r = side / sqrt(3); B1 = B2 = V1, B3 = B4 = V2, B5 = B6 = V3; all cables one length.
    """

    kind: Literal["octahedral"] = "octahedral"
    side: Length = Field(1.4, description="platform edge length s [m]")
    cable_length: Length = Field(2.0, description="length l of all six cables [m]")

    @model_validator(mode="after")
    def _cables_reach_over_edge(self) -> OctahedralGeometry:
        if self.cable_length <= self.side / 2:
            raise ValueError(
                f"cable_length = {self.cable_length} m must exceed half the platform edge "
                f"(side / 2 = {self.side / 2} m), otherwise the drone cannot hang over its edge"
            )
        return self

    def platform_points(self) -> np.ndarray:
        r = self.side / math.sqrt(3.0)
        angles = np.radians([0.0, 0.0, 120.0, 120.0, 240.0, 240.0])
        return np.stack([r * np.cos(angles), r * np.sin(angles), np.zeros(6)], axis=1)

    def cable_lengths(self) -> np.ndarray:
        return np.full(6, self.cable_length)


class GenericGeometry(_Frozen):
    """A generic FlyCrane: six platform points B'_i (platform frame, relative to P) and lengths."""

    kind: Literal["generic"] = "generic"
    platform_points_: tuple[Point, Point, Point, Point, Point, Point] = Field(
        alias="platform_points", description="B'_1..B'_6 in the platform frame [m]"
    )
    cable_lengths_: tuple[Length, Length, Length, Length, Length, Length] = Field(
        alias="cable_lengths", description="l_1..l_6 [m]"
    )

    model_config = ConfigDict(
        frozen=True, extra="forbid", populate_by_name=True, allow_inf_nan=False
    )

    @model_validator(mode="after")
    def _each_drone_has_a_triangle(self) -> GenericGeometry:
        points, lengths = self.platform_points(), self.cable_lengths()
        for k, (i, j) in enumerate(DRONE_CABLES):
            edge = float(np.linalg.norm(points[j] - points[i]))
            name = f"drone {k + 1} (cables {i + 1} and {j + 1})"
            if edge < 1e-6:
                raise ValueError(
                    f"platform_points: {name} needs distinct base points B{i + 1} and B{j + 1}"
                )
            li, lj = lengths[i], lengths[j]
            if not (li + lj > edge and abs(li - lj) < edge):
                raise ValueError(
                    f"cable_lengths: {name}: lengths {li} m and {lj} m cannot form a triangle "
                    f"over their platform edge of {edge:.6g} m"
                )
        return self

    def platform_points(self) -> np.ndarray:
        return np.asarray(self.platform_points_, dtype=float)

    def cable_lengths(self) -> np.ndarray:
        return np.asarray(self.cable_lengths_, dtype=float)


class Perturbation(_Frozen):
    """The wrench-perturbation ellipsoid (w - w0)^T E (w - w0) <= 1 (design.md section 5).

    Either the shortcut E = diag(1/df^2 I3, 1/dt^2 I3), or a full symmetric positive definite
    6x6 ``matrix`` (force rows first, then torque rows, at P in world axes).
    """

    force: PerturbationRadius = Field(2.0, description="df: force perturbation radius [N]")
    torque: PerturbationRadius = Field(0.3, description="dt: torque perturbation radius [N m]")
    matrix: tuple[tuple[float, ...], ...] | None = Field(
        None, description="full E (6x6, SPD); overrides force/torque when given"
    )

    @field_validator("matrix")
    @classmethod
    def _symmetric_positive_definite(
        cls, value: tuple[tuple[float, ...], ...] | None
    ) -> tuple[tuple[float, ...], ...] | None:
        if value is None:
            return value
        e = np.asarray(value, dtype=float)
        if e.shape != (6, 6):
            raise ValueError(f"must be 6x6, got shape {e.shape}")
        if not np.all(np.isfinite(e)):
            raise ValueError("must contain finite numbers only")
        # Its inverse scales the tension ranges: entries beyond 1/MIN_PERTURBATION^2 overflow.
        if np.abs(e).max() > MAX_FORCE**2:
            raise ValueError(f"entries must be at most {MAX_FORCE**2:g} in size")
        # Relative tolerance: values typed by hand or printed with ~12 digits must pass.
        if not np.allclose(e, e.T, rtol=1e-9, atol=1e-12 * np.abs(e).max()):
            raise ValueError("must be symmetric")
        try:
            np.linalg.cholesky(e)
        except np.linalg.LinAlgError:
            eig = np.linalg.eigvalsh(e).min()
            raise ValueError(f"must be positive definite (smallest eigenvalue {eig:.3g})") from None
        return value

    def ellipsoid_matrix(self) -> np.ndarray:
        """E, the 6x6 shape matrix of the perturbation ellipsoid."""
        if self.matrix is not None:
            return np.asarray(self.matrix, dtype=float)
        return np.diag([self.force**-2] * 3 + [self.torque**-2] * 3)


class SystemSpec(_Frozen):
    """Complete description of a FlyCrane system. Defaults: design.md section 5 benchmark."""

    geometry: OctahedralGeometry | GenericGeometry = Field(
        default_factory=OctahedralGeometry, discriminator="kind"
    )
    platform_mass: Mass = Field(1.5, description="platform plus payload mass [kg]")
    com_offset: Point = Field(
        (0.0, 0.0, 0.0), description="centre of mass c' relative to P, platform frame [m]"
    )
    drone_mass: DroneMasses = Field(
        (1.0, 1.0, 1.0), description="mass M_k of each drone [kg]; one number sets all three"
    )
    max_thrust: DroneForces = Field(
        (25.0, 25.0, 25.0), description="maximum thrust h_k [N]; one number sets all three"
    )
    tension_min: CableNonNegativeForces = Field(
        (0.5,) * 6, description="lower tension bound f_lo_i [N]; one number sets all six"
    )
    tension_max: CableForces = Field(
        (30.0,) * 6, description="upper tension bound f_hi_i [N]; one number sets all six"
    )
    perturbation: Perturbation = Field(default_factory=Perturbation)
    gravity: Annotated[float, Field(gt=0.0, le=MAX_GRAVITY, strict=True)] = Field(
        9.81, description="g [m/s^2]"
    )

    @model_validator(mode="after")
    def _limits_are_consistent(self) -> SystemSpec:
        lo, hi = np.array(self.tension_min), np.array(self.tension_max)
        weight = np.array(self.drone_mass) * self.gravity
        thrust = np.array(self.max_thrust)
        reasons = [
            f"tension_max: cable {i + 1} upper bound {hi[i]} N must exceed its lower bound "
            f"tension_min = {lo[i]} N"
            for i in np.flatnonzero(hi <= lo)
        ] + [
            f"max_thrust: drone {k + 1} thrust {thrust[k]} N does not exceed its own weight "
            f"{weight[k]:.4g} N"
            for k in np.flatnonzero(thrust <= weight)
        ]
        if reasons:
            raise ValueError("; ".join(reasons))
        return self


#: Named systems users can ask for instead of a full description.
SYSTEM_PRESETS: dict[str, SystemSpec] = {"benchmark": SystemSpec()}


def system_preset(name: str) -> SystemSpec:
    """The preset ``name``, or a :class:`SystemSpecError` listing the known ones."""
    try:
        return SYSTEM_PRESETS[name]
    except KeyError:
        known = ", ".join(sorted(SYSTEM_PRESETS))
        raise SystemSpecError(
            [FieldProblem("system", f"unknown preset {name!r}; known: {known}")]
        ) from None


def problems_from_validation_error(error: ValidationError) -> list[FieldProblem]:
    """Field-named problems from a pydantic error (locations joined as ``a.b[2]``)."""
    return [
        FieldProblem(dotted(item["loc"]) or "system", item["msg"])
        for item in readable_errors(error.errors())
    ]


def system_from_dict(data: dict, source: str | None = None) -> SystemSpec:
    """Validate a plain mapping as a :class:`SystemSpec`, raising :class:`SystemSpecError`."""
    try:
        return SystemSpec.model_validate(data)
    except ValidationError as error:
        raise SystemSpecError(problems_from_validation_error(error), source) from None


def load_system(path: str | Path) -> SystemSpec:
    """Read a system from a ``.toml`` or ``.json`` file.

    Raises
    ------
    SystemSpecError
        If the file cannot be parsed or a field is invalid; the error names the field.
    """
    path = Path(path)
    try:
        text = read_text(path)
    except InputError as error:
        raise SystemSpecError(error.problems, str(path)) from None
    try:
        if path.suffix.lower() == ".toml":
            data = tomllib.loads(text)
        elif path.suffix.lower() == ".json":
            data = json.loads(text)
        else:
            raise SystemSpecError(
                [FieldProblem("file", f"unknown extension {path.suffix!r}, use .toml or .json")],
                str(path),
            )
    except (tomllib.TOMLDecodeError, json.JSONDecodeError) as error:
        raise SystemSpecError([FieldProblem("file", f"not valid: {error}")], str(path)) from None
    return system_from_dict(data, str(path))


def save_system(spec: SystemSpec, path: str | Path) -> None:
    """Write a system as ``.toml`` or ``.json`` (by extension); loading it gives it back."""
    path = Path(path)
    data = spec.model_dump(mode="json", by_alias=True, exclude_none=True)
    if path.suffix.lower() == ".toml":
        path.write_text(tomli_w.dumps(data), encoding="utf-8")
    elif path.suffix.lower() == ".json":
        path.write_text(json.dumps(data, indent=2) + "\n", encoding="utf-8")
    else:
        raise SystemSpecError(
            [FieldProblem("file", f"unknown extension {path.suffix!r}, use .toml or .json")],
            str(path),
        )
