"""What the benchmark scripts that read flight or task directories share: a directory that
is not what the script reads ends it with one line naming the directory and why, and exit
status 2 (argparse's for a bad argument), not a traceback.

The scripts run as ``python benchmarks/NAME.py``, so they import this module by its bare
name, as they import :func:`sitl_seeds.seeds`.
"""

from __future__ import annotations

import argparse
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from flycrane.errors import FlyCraneError

#: What reading a directory raises when it is not a flight or a task of this version: a
#: missing or unreadable file, a document without a field or with a value that does not
#: parse, and the project's own (InputError, TaskDirectoryError, AlignmentError).
INPUT_ERRORS = (OSError, KeyError, ValueError, FlyCraneError)


@contextmanager
def exit_if_unreadable(parser: argparse.ArgumentParser, directory: Path) -> Iterator[None]:
    """Turn any of :data:`INPUT_ERRORS` raised inside into ``error: DIRECTORY: reason`` on
    stderr and exit status 2."""
    try:
        yield
    except INPUT_ERRORS as error:
        parser.exit(2, f"error: {directory}: {error}\n")


def at_least_one(text: str) -> int:
    """An argparse type: a count of runs or seeds, 1 or more (a median of none is not a
    figure)."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a whole number") from None
    if value < 1:
        raise argparse.ArgumentTypeError(f"{value} runs measure nothing: give 1 or more")
    return value
