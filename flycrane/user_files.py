"""Files a user names (a task, a system, a scene, a mesh, a log): checked before reading.

A path can name a device that never ends (``/dev/zero``), a FIFO that blocks, a directory,
a file far larger than any description, or bytes that are not text. Each is refused with
the field and the reason before more than a bounded number of bytes is read; the caller
says which file (the error's source).
"""

from __future__ import annotations

import stat
from pathlib import Path

from flycrane.errors import FieldProblem, InputError

#: Largest text description (task, system or scene) [bytes]: a scene of inline meshes of
#: tens of thousands of triangles fits.
MAX_TEXT_BYTES = 16 * 2**20
#: Largest mesh file [bytes]: about 1.3 million triangles as binary STL.
MAX_MESH_BYTES = 64 * 2**20


def regular_file(path: Path, field: str, limit: int | None = None) -> Path:
    """``path`` if it names a regular file of at most ``limit`` bytes (any size without).

    Raises
    ------
    InputError
        No such file, not a regular file, or larger than ``limit`` (field ``field``).
    """
    try:
        info = path.stat()
    except OSError as error:
        raise InputError([FieldProblem(field, str(error.strerror or error))]) from None
    if not stat.S_ISREG(info.st_mode):
        raise InputError([FieldProblem(field, "not a regular file")])
    if limit is not None and info.st_size > limit:
        raise InputError(
            [FieldProblem(field, f"{info.st_size} bytes, more than the {limit} allowed")]
        )
    return path


def read_text(path: Path, field: str = "file", limit: int = MAX_TEXT_BYTES) -> str:
    """The UTF-8 text of a regular file of at most ``limit`` bytes.

    Raises
    ------
    InputError
        As :func:`regular_file`, or the bytes are not UTF-8 (field ``field``).
    """
    regular_file(path, field, limit)
    try:
        with path.open("rb") as handle:
            data = handle.read(limit + 1)  # a file may grow after its size was read
    except OSError as error:
        raise InputError([FieldProblem(field, str(error.strerror or error))]) from None
    if len(data) > limit:
        raise InputError([FieldProblem(field, f"more than the {limit} bytes allowed")])
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError as error:
        raise InputError([FieldProblem(field, f"not UTF-8 text (byte {error.start})")]) from None


def output_directory(path: str | Path, field: str = "--out") -> Path:
    """``path`` made a directory to write into (with its parents), or an error naming
    ``field``: an empty name (not the current directory by accident), an existing file
    there, a parent that is a file, no permission.

    Raises
    ------
    InputError
        The directory cannot be made or is not one (field ``field``).
    """
    if not str(path).strip():
        raise InputError([FieldProblem(field, "an empty directory name")])
    path = Path(path)
    try:
        path.mkdir(parents=True, exist_ok=True)
    except OSError as error:
        reason = "exists and is not a directory" if path.exists() else error.strerror or error
        raise InputError([FieldProblem(field, f"{path}: {reason}")]) from None
    return path
