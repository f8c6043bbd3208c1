"""``.parm`` files: the vehicle parameters a mission assumes, one ``NAME VALUE`` per line.

The format of ArduPilot's default parameter files, Mission Planner's "Load from file" and
MAVProxy's ``param load``: ``#`` starts a comment (a line of its own or after a value);
names are ArduPilot's (upper case, digits, underscore, at most 16 characters). Every
exported parameter carries a comment saying why the plan needs it.
"""

from __future__ import annotations

import math
import re
from collections.abc import Mapping
from pathlib import Path

from flycrane.errors import FieldProblem, InputError

#: ArduPilot's parameter names: AP_MAX_NAME_SIZE is 16.
NAME = re.compile(r"^[A-Z][A-Z0-9_]{0,15}$")


def parameter_file_text(
    values: Mapping[str, float], reasons: Mapping[str, str], header: str = ""
) -> str:
    """A ``.parm`` file of ``values``, each preceded by its reason as a comment."""
    lines = [f"# {line}" if line else "#" for line in header.splitlines()]
    for name, value in values.items():
        if not NAME.match(name):
            raise ValueError(f"not an ArduPilot parameter name: {name!r}")
        if name in reasons:
            lines.append(f"# {reasons[name]}")
        lines.append(f"{name} {value:.9g}")
    return "\n".join(lines) + "\n"


def parse_parameter_file(text: str, source: str = ".parm") -> dict[str, float]:
    """``{NAME: value}`` of a ``.parm`` text.

    Raises
    ------
    InputError
        Naming every bad line (``line 3``) and why.
    """
    values: dict[str, float] = {}
    problems = []
    for number, raw in enumerate(text.splitlines(), start=1):
        line = raw.split("#", 1)[0].replace(",", " ").strip()
        if not line:
            continue
        fields = line.split()
        where = f"line {number}"
        if len(fields) != 2:
            problems.append(FieldProblem(where, f"expected 'NAME VALUE', got {raw.strip()!r}"))
            continue
        name, text_value = fields
        if not NAME.match(name):
            problems.append(FieldProblem(where, f"not an ArduPilot parameter name: {name!r}"))
            continue
        try:
            value = (
                float(int(text_value, 16))
                if text_value.lower().startswith("0x")
                else float(text_value)
            )
        except ValueError:
            problems.append(FieldProblem(where, f"{name}: not a number: {text_value!r}"))
            continue
        if not math.isfinite(value):
            problems.append(FieldProblem(where, f"{name}: not finite: {text_value!r}"))
            continue
        if name in values:
            problems.append(FieldProblem(where, f"{name} given twice"))
            continue
        values[name] = value
    if problems:
        raise InputError(problems, source=source)
    return values


def read_parameter_file(path: Path) -> dict[str, float]:
    """:func:`parse_parameter_file` of the file at ``path``."""
    return parse_parameter_file(path.read_text(encoding="utf-8"), source=str(path))
