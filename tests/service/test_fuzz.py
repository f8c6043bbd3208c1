"""Fuzzing the service against its own OpenAPI description (issue 10, "What it must show").

A short run of ``benchmarks/fuzz_service.py`` (schemathesis, every phase, a fixed seed,
at most half a minute of requests) against ``flycrane serve`` on loopback: no response may be a
server error or differ from what the OpenAPI document says (status, content type, headers,
body schema). The long run and its figures are in BENCHMARKS.md.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

SCRIPT = Path(__file__).resolve().parents[2] / "benchmarks" / "fuzz_service.py"


def test_no_server_error_and_every_response_as_documented():
    run = subprocess.run(
        [sys.executable, str(SCRIPT), "--max-examples", "5", "--max-time", "30", "--seed", "1"],
        capture_output=True,
        text=True,
        timeout=240,
        check=False,
    )
    assert run.returncode == 0, run.stdout[-10_000:] + run.stderr[-5_000:]
    assert "failures: 0 kinds" in run.stdout
    assert "/healthz 200 after the run" in run.stdout
