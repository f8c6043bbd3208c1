"""MAVLink FTP: putting a file on a vehicle (pymavlink's ``mavftp`` over a
:class:`~missions.mavlink.transport.VehicleLink`).

pymavlink's :class:`~pymavlink.mavftp.MAVFTP` drives the protocol (sessions, bursts,
retries) against a connection object that sends FILE_TRANSFER_PROTOCOL and receives its
replies. A link's reader thread owns the socket, so :class:`_LinkPort` gives MAVFTP that
interface over the link: sends go through :meth:`VehicleLink.send`, replies come from an
inbox. On ArduPilot, ``/NAME`` lands in the root of its file system (SITL: the instance's
working directory), where a Lua script opens ``NAME``.
"""

from __future__ import annotations

import io
from typing import Any

from pymavlink.mavftp import MAVFTP, MAVFTPSettings

from missions.mavlink.errors import MavlinkError
from missions.mavlink.transport import VehicleLink

#: How long FTP waits for a quiet link before it calls a transfer over [s]. MAVFTP's
#: default (3.7 s) suits a slow radio; replies on SITL's loopback come in milliseconds.
IDLE_DETECTION_S = 1.0  # > read_retry_time, as MAVFTP requires


class FtpError(MavlinkError):
    """An FTP transfer failed: which vehicle, which file, and MAVFTP's error."""

    def __init__(self, vehicle: str, remote: str, reason: str) -> None:
        self.vehicle, self.remote, self.reason = vehicle, remote, reason
        super().__init__(f"{vehicle}: FTP put {remote} failed: {reason}")


class _LinkPort:
    """The part of a pymavlink connection MAVFTP uses, over a VehicleLink (module
    docstring)."""

    def __init__(self, link: VehicleLink) -> None:
        self.link = link
        self.mav = self
        self.source_system = link.source.system
        self.source_component = link.source.component
        self.inbox = link.subscribe(("FILE_TRANSFER_PROTOCOL",))

    def file_transfer_protocol_send(
        self, network: int, target_system: int, target_component: int, payload: Any
    ) -> None:
        self.link.send(
            (
                "FILE_TRANSFER_PROTOCOL",
                {
                    "target_network": network,
                    "target_system": target_system,
                    "target_component": target_component,
                    "payload": list(payload),
                },
            )
        )

    def recv_match(self, type: Any = None, timeout: float = 0.1, **_: Any) -> Any:
        return self.inbox.get(timeout)

    def close(self) -> None:
        self.inbox.close()


def put_file(link: VehicleLink, data: bytes, remote: str, timeout: float) -> None:
    """Write ``data`` to ``remote`` (an absolute path, e.g. ``/trajectory.bin``) on the
    vehicle.

    Raises
    ------
    FtpError
        The vehicle refused or the transfer did not finish within ``timeout`` [s].
    """
    port = _LinkPort(link)
    try:
        settings = MAVFTPSettings(
            [
                ("debug", int, 0),
                ("pkt_loss_tx", int, 0),
                ("pkt_loss_rx", int, 0),
                ("max_backlog", int, 5),
                ("burst_read_size", int, 80),
                ("write_size", int, 200),
                ("write_qsize", int, 5),
                ("idle_detection_time", float, IDLE_DETECTION_S),
                ("read_retry_time", float, 0.5),
                ("retry_time", float, 0.5),
            ]
        )
        ftp = MAVFTP(port, link.target.system, link.target.component, settings)
        started = ftp.cmd_put(["upload", remote], fh=io.BytesIO(data))
        outcome = started if started.error_code else ftp.process_ftp_reply("CreateFile", timeout)
    finally:
        port.close()
    if outcome.error_code:
        raise FtpError(link.name, remote, repr(outcome.error_code))
