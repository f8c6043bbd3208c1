"""Files a user names: devices, directories, oversized and non-UTF-8 files are refused
with the field and the reason, before more than the limit is read."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

from flycrane.errors import InputError
from flycrane.user_files import output_directory, read_text, regular_file


def test_text_of_a_regular_file(tmp_path: Path):
    path = tmp_path / "task.json"
    path.write_text('{"scene": "rescue"} é', encoding="utf-8")
    assert read_text(path) == '{"scene": "rescue"} é'


@pytest.mark.parametrize(
    ("make", "reason"),
    [
        (lambda d: Path("/dev/zero"), "not a regular file"),  # would never end
        (lambda d: d, "not a regular file"),
        (lambda d: d / "nowhere.toml", "No such file"),
        (lambda d: _fifo(d), "not a regular file"),  # would block
        (lambda d: _write(d / "big.toml", b"x" * 101), "101 bytes, more than the 100 allowed"),
        (lambda d: _write(d / "bin.toml", b"ok\xff\xfe"), "not UTF-8 text (byte 2)"),
    ],
)
def test_refused_with_the_field_and_the_reason(tmp_path: Path, make, reason):
    with pytest.raises(InputError) as info:
        read_text(make(tmp_path), "system", limit=100)
    (problem,) = info.value.problems
    assert problem.field == "system" and reason in problem.reason


def test_a_size_limit_only_where_given(tmp_path: Path):
    path = _write(tmp_path / "flight.tlog", b"\x00" * 1000)
    assert regular_file(path, "tlogs") == path
    with pytest.raises(InputError, match="more than the 999 allowed"):
        regular_file(path, "tlogs", 999)


def _write(path: Path, data: bytes) -> Path:
    path.write_bytes(data)
    return path


def _fifo(directory: Path) -> Path:
    path = directory / "pipe.toml"
    os.mkfifo(path)
    return path


def test_an_output_directory_is_made_or_refused_naming_the_option(tmp_path: Path):
    assert output_directory(tmp_path / "a" / "b").is_dir()
    (tmp_path / "file").write_text("mine", encoding="utf-8")
    for path, reason in (
        (tmp_path / "file", "exists and is not a directory"),
        (tmp_path / "file" / "sub", "Not a directory"),
    ):
        with pytest.raises(InputError) as info:
            output_directory(path)
        (problem,) = info.value.problems
        assert problem.field == "--out" and reason in problem.reason
    assert (tmp_path / "file").read_text(encoding="utf-8") == "mine"
