"""Upload addresses the reviewer tried: serial devices that cannot be opened (a 500 before,
from pymavlink's serial link) and port 0 (a listener on a port nobody knows)."""

from __future__ import annotations

import os

import pytest

from tests.missions.loopback import waypoint_mission
from tests.service.conftest import running_service
from tests.service.fabricated import done_task

OTHERS = ["udpout:127.0.0.1:15001", "udpout:127.0.0.1:15002"]


def fabricated(client) -> str:
    missions = [waypoint_mission(k, 3) for k in (1, 2, 3)]
    return done_task(client.app.state.service, missions, [{}] * 3)


def test_serial_devices_that_do_not_exist_are_502_naming_each_and_free_the_slot(tmp_path):
    devices = [f"/dev/ttyFLYCRANE_NONE{k},57600" for k in (1, 2, 3)]
    assert not any(os.path.exists(d.split(",")[0]) for d in devices)
    allowed = (r"/dev/ttyFLYCRANE_NONE[0-9]",)
    with running_service(tmp_path, upload_devices=allowed, max_concurrent_uploads=1) as client:
        task = fabricated(client)
        for _ in range(2):  # the one upload slot is free again after each
            response = client.post(f"/v1/tasks/{task}/upload", json={"vehicles": devices})
            assert response.status_code == 502, response.text
            outcome = response.json()["vehicles"]
            for drone, (device, vehicle) in enumerate(zip(devices, outcome, strict=True), 1):
                assert vehicle["drone"] == drone and vehicle["vehicle"] == device
                assert not vehicle["ok"]
                assert vehicle["detail"].startswith(f"drone {drone} ({device}): cannot open")
                assert "No such file or directory" in vehicle["detail"]


def test_a_baud_rate_no_link_runs_at_is_422_naming_the_vehicle(tmp_path):
    """10**20 baud reached pyserial, whose OverflowError was a 500."""
    controller, device = os.openpty()
    try:
        name = os.ttyname(device)
        vehicles = [f"{name},{10**20}", *OTHERS]
        with running_service(tmp_path, upload_devices=(r"/dev/pts/[0-9]+",)) as client:
            task = fabricated(client)
            response = client.post(f"/v1/tasks/{task}/upload", json={"vehicles": vehicles})
        assert response.status_code == 422, response.text
        assert f"baud {10**20} outside 1..12000000" in response.text
    finally:
        os.close(controller)
        os.close(device)


@pytest.mark.parametrize(
    "address",
    [
        "udp:127.0.0.1:0",
        "udpin:127.0.0.1:0",
        "udpout:127.0.0.1:0",
        "tcp:127.0.0.1:0",
        "tcpin:127.0.0.1:0",
        "udpin://127.0.0.1:0",
    ],
)
def test_port_0_is_refused_in_every_form(tmp_path, address):
    with running_service(tmp_path) as client:
        task = fabricated(client)
        response = client.post(f"/v1/tasks/{task}/upload", json={"vehicles": [address, *OTHERS]})
    # refused as input (422), not a link opened and waited for (502 after its timeout)
    assert response.status_code == 422, response.text
    (problem,) = response.json()["detail"]
    assert problem["loc"] == ["body", "vehicles[0]"]
    assert problem["msg"] == f"{address!r}: port 0 outside 1..65535"
