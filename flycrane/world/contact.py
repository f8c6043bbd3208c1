"""What a collision check finds: a contact between two bodies, or how far one
configuration is from touching (the names of the robot body and of the obstacle, or the
ground).
"""

from __future__ import annotations

from dataclasses import dataclass

#: The name of the ground, as an obstacle.
GROUND = "ground"


@dataclass(frozen=True)
class Contact:
    """One collision of a configuration: which robot body touches what, and how deep.

    ``depth`` is the penetration depth [m] where fcl reports one, or the shortfall of a
    separation (min distance - actual distance) for the closed-form self-checks.
    """

    body: str
    other: str
    depth: float

    def __str__(self) -> str:
        return f"{self.body} hits {self.other} (by {self.depth:.3g} m)"


@dataclass(frozen=True)
class Clearance:
    """How far one configuration is from touching: the closest robot body, the obstacle
    (or ``"ground"``) it is closest to, and their distance [m]."""

    distance: float
    body: str
    other: str

    def __str__(self) -> str:
        return f"{self.body} {self.distance:.3f} m from {self.other}"
