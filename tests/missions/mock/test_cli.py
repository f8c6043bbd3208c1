"""``flycrane mock-autopilot`` as a user runs it: a process a ground station can talk to."""

from __future__ import annotations

import os
import shutil
import signal
import subprocess
import sys

import pytest

from flycrane.cli import main
from missions.mavlink.policy import RetryPolicy
from missions.mavlink.transport import VehicleLink
from tests.missions.loopback import free_udp_port

# the console script next to this interpreter, as installed by `make`
FLYCRANE = [shutil.which("flycrane", path=os.path.dirname(sys.executable)) or "flycrane"]


def test_mock_autopilot_process_answers_a_heartbeat_waiting_client():
    port = free_udp_port()
    process = subprocess.Popen(
        [
            *FLYCRANE,
            "mock-autopilot",
            "--port",
            str(port),
            "--system-id",
            "7",
            "--speedup",
            "4",
            "--home",
            "46.5",
            "6.6",
            "400",
        ],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env={**os.environ, "PYTHONUNBUFFERED": "1"},
    )
    try:
        policy = RetryPolicy(heartbeat_timeout_s=15.0, gcs_heartbeat_interval_s=0.2)
        with VehicleLink(f"udpout:127.0.0.1:{port}", policy) as link:
            info = link.wait_heartbeat()
    finally:
        process.send_signal(signal.SIGTERM)
        _, err = process.communicate(timeout=10)
    assert (info.system_id, info.autopilot, info.vehicle_type) == (7, 3, 2)  # ArduPilot quad
    assert process.returncode == 0, err
    assert f"system 7 on udpin:127.0.0.1:{port}" in err
    assert "Traceback" not in err


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--speedup", "0"], "--speedup: must be in (0, 1000], got 0"),
        (["--port", "http"], "invalid int value: 'http'"),
    ],
)
def test_bad_arguments_exit_non_zero_with_a_message(args, message):
    done = subprocess.run(
        [*FLYCRANE, "mock-autopilot", *args, "--duration", "1"],
        capture_output=True,
        text=True,
        timeout=30,
    )
    assert done.returncode == 2
    assert message in done.stderr
    assert "Traceback" not in done.stderr


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--port", "70000"], "port 70000 outside"),
        (["--home", "91", "0", "0"], "lat_deg: must be in [-90, 90]"),
        (["--drop", "1.5"], "drop_incoming: must be in [0, 1]"),
        (["--system-id", "0"], "system_id: must be in 1..255"),
        (["--slowdown", "2"], "waypoint_slowdown: must be in [0, 1]"),
        (["--connection", "carrier-pigeon"], "expected udpin:HOST:PORT"),
        (["--duration", "0"], "--duration: must be in (0, 1e+06], got 0"),
        # each used to start a mock that could not run, or to end in a traceback
        (["--duration", "inf"], "--duration: must be in (0, 1e+06], got inf"),
        (["--speedup", "inf"], "--speedup: must be in (0, 1000], got inf"),
        (["--seed", "-1"], "seed: must be in 0..4294967295"),
        (["--noise", "nan"], "--noise: must be in [0, 100], got nan"),
        (["--speed-scale", "inf"], "speed_scale: must be finite and > 0"),
        (["--start-delay", "nan"], "start_delay_s: must be finite and >= 0"),
        (["--boot-no-space", "inf"], "--boot-no-space: must be in [0, 1e+06], got inf"),
        (["--home", "0", "0", "inf"], "--home.alt_m: must be in [-100000, 100000]"),
        # each was accepted: a mock that overflowed its timer, flew a kilometre-high home,
        # or ran as fast as a core would let it
        (["--duration", "1e300"], "--duration: must be in (0, 1e+06], got 1e+300"),
        (["--home", "47", "8", "1e9"], "--home.alt_m: must be in [-100000, 100000]"),
        (["--noise", "1e300"], "--noise: must be in [0, 100], got 1e+300"),
        (["--boot-no-space", "1e300"], "--boot-no-space: must be in [0, 1e+06]"),
        (["--speedup", "1e12"], "--speedup: must be in (0, 1000], got 1000000000000.0"),
        (["--host", "999.1.1.1"], "--host: udpin:999.1.1.1:14550: "),
    ],
)
def test_invalid_values_are_named(capsys, args, message):
    assert main(["mock-autopilot", *args]) == 2
    err = capsys.readouterr().err
    assert err.startswith("flycrane mock-autopilot: error:") and message in err
