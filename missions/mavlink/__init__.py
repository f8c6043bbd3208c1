"""MAVLink transport of FlyCrane missions: upload, start, telemetry, and a mock ArduCopter.

Ground side (one module per protocol concept):

- :mod:`.transport` - connection strings, :class:`VehicleLink` (one reader thread a link)
- :mod:`.policy` - :class:`RetryPolicy`, the stated timeouts and retries
- :mod:`.messages` - messages as plain data, MissionItem <-> MISSION_ITEM_INT
- :mod:`.transfer` - mission upload / download / clear on one link
- :mod:`.upload` - upload with read-back verification (:func:`upload_and_verify`)
- :mod:`.commands` - position streams, arming, one common MISSION_START
- :mod:`.telemetry` - :class:`TelemetryRecorder`
- :mod:`.fleet` - :class:`Fleet`: all of the above on N vehicles at once
- :mod:`.errors` - typed errors carrying vehicle and MAVLink result codes

Vehicle side (tests, and ``flycrane mock-autopilot``): :mod:`.mock_autopilot`,
:mod:`.mock_mission` (mission protocol), :mod:`.mock_params` (parameters),
:mod:`.mock_flight` (the mission flown in simulated time: :mod:`.mock_spline` ArduCopter's
spline legs, :mod:`.mock_straight` the mock's own straight ones), :mod:`.mock_config`,
:mod:`.faults` (lossy links).
"""

from __future__ import annotations

from missions.mavlink.commands import StartReport
from missions.mavlink.errors import (
    CommandRejectedError,
    FinalAckTimeoutError,
    FleetError,
    MavlinkError,
    MavlinkTimeoutError,
    MissionTransferError,
    MissionVerificationError,
)
from missions.mavlink.faults import FaultInjection
from missions.mavlink.fleet import Fleet, upload_to_vehicles
from missions.mavlink.mock_autopilot import MockAutopilot, MockConfig
from missions.mavlink.mock_config import Dynamics, Geodetic, Imperfections
from missions.mavlink.policy import RetryPolicy
from missions.mavlink.sim_clock import SimClock
from missions.mavlink.telemetry import TelemetryRecorder, VehicleTelemetry
from missions.mavlink.transport import VehicleLink
from missions.mavlink.upload import UploadReport, Verification, upload_and_verify

__all__ = [
    "CommandRejectedError",
    "Dynamics",
    "FaultInjection",
    "FinalAckTimeoutError",
    "Fleet",
    "FleetError",
    "Geodetic",
    "Imperfections",
    "MavlinkError",
    "MavlinkTimeoutError",
    "MissionTransferError",
    "MissionVerificationError",
    "MockAutopilot",
    "MockConfig",
    "RetryPolicy",
    "SimClock",
    "StartReport",
    "TelemetryRecorder",
    "UploadReport",
    "VehicleLink",
    "VehicleTelemetry",
    "Verification",
    "upload_and_verify",
    "upload_to_vehicles",
]
