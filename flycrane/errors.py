"""Typed errors of the ``flycrane`` package.

Every error derives from :class:`FlyCraneError` and carries the facts a user needs to act on
it (which field, which cable or drone, by how much), not only a message.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass


class FlyCraneError(Exception):
    """Root of every error raised on purpose by this project."""


@dataclass(frozen=True)
class FieldProblem:
    """One invalid input field: a dotted location (``"drone_mass"``, ``"q[4]"``) and why."""

    field: str
    reason: str

    def __str__(self) -> str:
        return f"{self.field}: {self.reason}"


class InputError(FlyCraneError, ValueError):
    """Invalid user input; ``problems`` names every offending field and the reason."""

    def __init__(self, problems: Sequence[FieldProblem], source: str | None = None) -> None:
        self.problems = tuple(problems)
        self.source = source
        where = f"{source}: " if source else ""
        super().__init__(where + "; ".join(str(p) for p in self.problems))


class SystemSpecError(InputError):
    """A FlyCrane system description (file or object) is invalid."""


class ConfigurationError(InputError):
    """An array of configurations has the wrong shape or invalid values."""
