"""Bounded number types for every input schema (systems, scenes, tasks).

Every number a user gives must be finite and of a size the model can compute with: a
coordinate of 1e308 m squares to infinity in the collision broad phase and the body is then
never checked, a mass of 1e308 kg makes every weight infinite. The bounds below are far
beyond any FlyCrane (a few metres, a few kilograms, tens of newtons) and small enough that
products, squares and reciprocals of them stay finite and well-resolved in float64. They
are limits of what is computable, not of what is sensible: the statics and collision
checks still refuse what cannot fly.

The types are strict: a number must be given as a number (``true`` or ``"3"`` is refused,
not read as 1 or 3); integers are accepted where a float is expected.
"""

from __future__ import annotations

import math
from typing import Annotated

from pydantic import Field

#: Largest coordinate, size or length of any geometry [m]: 10 km around the task origin.
MAX_LENGTH = 1.0e4
#: Largest mass [kg].
MAX_MASS = 1.0e4
#: Largest force [N] or torque [N m].
MAX_FORCE = 1.0e6
#: Smallest perturbation radius [N, N m]: E = diag(1 / df^2, ...) must stay finite.
MIN_PERTURBATION = 1.0e-6
#: Largest gravity [m/s^2].
MAX_GRAVITY = 100.0
#: Angles of orientations [rad]: every orientation has angles within one turn either way.
MAX_ANGLE = 2.0 * math.pi

Finite = Annotated[float, Field(allow_inf_nan=False, strict=True)]
Coordinate = Annotated[
    float, Field(ge=-MAX_LENGTH, le=MAX_LENGTH, allow_inf_nan=False, strict=True)
]
Length = Annotated[float, Field(gt=0.0, le=MAX_LENGTH, allow_inf_nan=False, strict=True)]
NonNegativeLength = Annotated[float, Field(ge=0.0, le=MAX_LENGTH, allow_inf_nan=False, strict=True)]
Angle = Annotated[float, Field(ge=-MAX_ANGLE, le=MAX_ANGLE, allow_inf_nan=False, strict=True)]
Mass = Annotated[float, Field(gt=0.0, le=MAX_MASS, allow_inf_nan=False, strict=True)]
Force = Annotated[float, Field(gt=0.0, le=MAX_FORCE, allow_inf_nan=False, strict=True)]
NonNegativeForce = Annotated[float, Field(ge=0.0, le=MAX_FORCE, allow_inf_nan=False, strict=True)]
PerturbationRadius = Annotated[
    float, Field(ge=MIN_PERTURBATION, le=MAX_FORCE, allow_inf_nan=False, strict=True)
]
Point = tuple[Coordinate, Coordinate, Coordinate]
Orientation = tuple[Angle, Angle, Angle]
#: The platform's tilt theta [rad]: the tilt-and-torsion chart's range (design.md s.3; a
#: negative tilt is phi + pi).
Tilt = Annotated[float, Field(ge=0.0, le=math.pi, allow_inf_nan=False, strict=True)]
#: The platform's orientation (phi, theta, sigma) [rad] in that chart.
PlatformOrientation = tuple[Angle, Tilt, Angle]
#: A configuration q (design.md s.3): position [m] and six angles [rad], all bounded.
Configuration = tuple[Coordinate, Coordinate, Coordinate, Angle, Tilt, Angle, Angle, Angle, Angle]
#: Longest planning time a run may be given [s]: a day.
MAX_TIME_BUDGET = 86_400.0
#: Seeds of the random number generators: OMPL's seed is a uint_fast32_t (at least 32
#: bits) and gets seed + 1.
#: The largest seed (the generators take 32 bits).
MAX_SEED = 2**32 - 1
Seed = Annotated[int, Field(ge=0, le=MAX_SEED, strict=True)]
