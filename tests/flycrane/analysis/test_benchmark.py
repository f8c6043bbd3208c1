"""The benchmark's result files: written whole or not at all, and an error names the file."""

from __future__ import annotations

import csv
import json

import pytest

from flycrane.analysis.benchmark import RunRecord, summarize, write_results

RECORDS = [
    RunRecord("rescue", "rrt", seed, "exact_solution", 0.5, 10, 20, 0.1, 1e9, 2e9, 1.0, 3e9)
    for seed in (0, 1)
]


def test_results_are_read_back_as_written(tmp_path):
    write_results(RECORDS, summarize(RECORDS), tmp_path)
    with (tmp_path / "runs.csv").open(newline="", encoding="utf-8") as handle:
        rows = list(csv.DictReader(handle))
    assert [int(r["seed"]) for r in rows] == [0, 1]
    summary = json.loads((tmp_path / "summary.json").read_text(encoding="utf-8"))
    assert [r["seed"] for r in summary["runs"]] == [0, 1]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["runs.csv", "summary.json"]


def test_a_file_that_cannot_be_written_is_named_and_not_left_half_written(tmp_path):
    """A full disk left summary.json cut at 4096 bytes, and its error named no file."""
    (tmp_path / "summary.json").mkdir()  # what stands in the way: replacing it fails
    with pytest.raises(OSError) as failed:
        write_results(RECORDS, summarize(RECORDS), tmp_path)
    assert failed.value.filename == str(tmp_path / "summary.json")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["runs.csv", "summary.json"]
    assert (tmp_path / "summary.json").is_dir()
