"""Connection strings and the first heartbeat."""

from __future__ import annotations

import time

import pytest

from missions.mavlink.errors import ConnectionStringError, MavlinkTimeoutError
from missions.mavlink.policy import RetryPolicy
from missions.mavlink.transport import ConnectionSpec, VehicleLink, parse_connection
from tests.missions.loopback import free_udp_port


@pytest.mark.parametrize(
    ("address", "spec", "device"),
    [
        ("udpin:0.0.0.0:14550", ConnectionSpec("udpin", "0.0.0.0", 14550), "udpin:0.0.0.0:14550"),
        (
            "udp:127.0.0.1:14550",
            ConnectionSpec("udpin", "127.0.0.1", 14550),
            "udpin:127.0.0.1:14550",
        ),
        (
            "udpout:10.0.0.2:14555",
            ConnectionSpec("udpout", "10.0.0.2", 14555),
            "udpout:10.0.0.2:14555",
        ),
        (
            "udpin://127.0.0.1:5000",
            ConnectionSpec("udpin", "127.0.0.1", 5000),
            "udpin:127.0.0.1:5000",
        ),
        ("tcp:localhost:5760", ConnectionSpec("tcp", "localhost", 5760), "tcp:localhost:5760"),
        ("tcpin:0.0.0.0:5760", ConnectionSpec("tcpin", "0.0.0.0", 5760), "tcpin:0.0.0.0:5760"),
        (
            "/dev/ttyUSB0,115200",
            ConnectionSpec("serial", device="/dev/ttyUSB0", baud=115200),
            "/dev/ttyUSB0",
        ),
        (
            "serial:/dev/ttyACM0:57600",
            ConnectionSpec("serial", device="/dev/ttyACM0"),
            "/dev/ttyACM0",
        ),
        (
            "/dev/serial/by-id/usb-ArduPilot",
            ConnectionSpec("serial", device="/dev/serial/by-id/usb-ArduPilot"),
            "/dev/serial/by-id/usb-ArduPilot",
        ),
    ],
)
def test_connection_strings(address, spec, device):
    parsed = parse_connection(address)
    assert parsed == spec
    assert parsed.mavutil_device() == device


@pytest.mark.parametrize(
    "address",
    ["", "udpin:14550", "udpout:host:0", "udpout:host:70000", "http://x:80", "COM",
     "/dev/ttyUSB0,0", f"/dev/ttyUSB0,{10**20}"],
)  # fmt: skip
def test_bad_connection_strings_name_the_address(address):
    with pytest.raises(ConnectionStringError) as error:
        parse_connection(address)
    assert error.value.address == address
    assert repr(address) in str(error.value)


def test_silent_port_times_out_at_heartbeat_within_the_stated_time():
    policy = RetryPolicy(heartbeat_timeout_s=0.5, gcs_heartbeat_interval_s=0.1)
    with VehicleLink(f"udpout:127.0.0.1:{free_udp_port()}", policy, name="ghost") as link:
        started = time.monotonic()
        with pytest.raises(MavlinkTimeoutError) as error:
            link.wait_heartbeat()
        elapsed = time.monotonic() - started
    assert (error.value.vehicle, error.value.stage, error.value.timeout_s) == (
        "ghost",
        "HEARTBEAT",
        0.5,
    )
    assert 0.5 <= elapsed < 0.8
