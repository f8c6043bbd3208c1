"""Typed errors of the ``flycrane`` package.

Every error derives from :class:`FlyCraneError` and carries the facts a user needs to act on
it (which field, which cable or drone, by how much), not only a message.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any


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

    def under(self, prefix: str) -> InputError:
        """The same problems named as fields of a document nested at ``prefix`` (a task's
        ``system``): the model's own checks name the fields of what they check."""
        return InputError([FieldProblem(f"{prefix}.{p.field}", p.reason) for p in self.problems])

    def about(self, what: object) -> InputError:
        """The same problems, each reason said of ``what`` (the file a field names)."""
        return InputError([FieldProblem(p.field, f"{what}: {p.reason}") for p in self.problems])


class SystemSpecError(InputError):
    """A FlyCrane system description (file or object) is invalid."""


class ConfigurationError(InputError):
    """An array of configurations has the wrong shape or invalid values."""


#: Values of discriminator fields (``kind``): pydantic puts the chosen union branch in an
#: error's location, which says nothing to the user that the field path does not.
UNION_TAGS = frozenset({"octahedral", "generic", "box", "cylinder", "sphere", "mesh"})

#: Error types of a union branch the input plainly did not mean (a dict given where the
#: other branch wanted a string or a list, or the other way round).
_WRONG_BRANCH: dict[type, frozenset[str]] = {
    dict: frozenset({"string_type", "list_type", "tuple_type"}),
    list: frozenset({"model_type", "dict_type", "model_attributes_type", "string_type"}),
    str: frozenset({"model_type", "dict_type", "model_attributes_type", "tuple_type"}),
}


def _is_field(part: int | str) -> bool:
    """Whether a location part names a field or an index, not a pydantic branch tag
    (``str``, ``tuple[...]``, ``function-after[...]``, a model's class name, a ``kind``)."""
    if isinstance(part, int):
        return True
    return not (
        part in ("str", "int", "float", "bool", "none")
        or "[" in part
        or part.startswith("function-")
        or part[:1].isupper()
        or part in UNION_TAGS
    )


def readable_errors(errors: Iterable[Mapping[str, Any]]) -> list[dict[str, Any]]:
    """Pydantic errors as ``{"loc", "msg", "type"}`` with field-only locations, without the
    errors of union branches the input plainly did not mean, duplicates dropped."""
    errors = list(errors)
    cleaned, seen = [], set()
    for error in errors:
        kind = next((k for k in _WRONG_BRANCH if isinstance(error.get("input"), k)), None)
        if kind is not None and error["type"] in _WRONG_BRANCH[kind]:
            continue
        loc = [part for part in error["loc"] if _is_field(part)]
        message = str(error["msg"]).removeprefix("Value error, ")
        key = (tuple(loc), message)
        if key not in seen:
            seen.add(key)
            cleaned.append({"loc": loc, "msg": message, "type": error["type"]})
    if cleaned or not errors:
        return cleaned
    return [{"loc": list(e["loc"]), "msg": str(e["msg"]), "type": e["type"]} for e in errors]


def dotted(loc: Sequence[int | str]) -> str:
    """A location as a user writes it: ``scene.obstacles[2].radius``."""
    text = ""
    for part in loc:
        if isinstance(part, int):
            text += f"[{part}]"
        else:
            text += ("." if text else "") + str(part).rstrip("_")
    return text


def field_messages(errors: Iterable[Mapping[str, Any]]) -> list[tuple[str, str]]:
    """Pydantic errors (``error.errors()``) as (field as a user writes it, message) pairs,
    for a command line's settings (:func:`readable_errors`, :func:`dotted`)."""
    return [(dotted(item["loc"]), item["msg"]) for item in readable_errors(errors)]
