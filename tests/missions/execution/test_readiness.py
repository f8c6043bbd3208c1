"""The check before the release, judged on the MAVLink messages a vehicle sends: a barometer
that drifted, a poor fix, a drone off its hold, each named with its drone. The expected
positions and altitudes come from pymap3d and the model's bounds, not from the check."""

from __future__ import annotations

import numpy as np
import pymap3d
import pytest
from pymavlink.dialects.v20 import ardupilotmega as mavlink

from missions.execution.readiness import judge_readiness
from missions.execution.team import EKF_NEEDED
from missions.options import GeodeticOrigin
from missions.position_error import PRESETS

ORIGIN = GeodeticOrigin()
HOME_HEIGHT = 0.5  #: the homes' height above the task's ground [m]
HOLDS = np.array([[0.0, 0.0, 6.0], [2.0, 0.0, 6.0], [1.0, 1.7, 6.0]])
NAMES = ["drone 1", "drone 2", "drone 3"]
MODEL = PRESETS["sitl"]


def reports(
    offsets: np.ndarray | None = None, baro: float = 0.0, drone: int = 1, fix: int = 3
) -> list[dict]:
    """What three drones at ``HOLDS`` (each estimate moved by ``offsets`` [m, ENU]) report;
    ``drone``'s estimated altitude ``baro`` above its GNSS altitude, its GNSS fix ``fix``."""
    offsets = np.zeros((3, 3)) if offsets is None else offsets
    sent = []
    for k, (hold, offset) in enumerate(zip(HOLDS, offsets, strict=True)):
        lat, lon, alt = pymap3d.enu2geodetic(
            *(hold + offset), ORIGIN.latitude, ORIGIN.longitude, ORIGIN.altitude
        )
        lat_e7, lon_e7, alt_mm = round(lat * 1e7), round(lon * 1e7), round(alt * 1000)
        relative_mm = round((alt - ORIGIN.altitude - HOME_HEIGHT) * 1000)
        gnss_mm = alt_mm - round(baro * 1000) if k == drone else alt_mm
        sent.append({
            "GLOBAL_POSITION_INT": mavlink.MAVLink_global_position_int_message(
                0, lat_e7, lon_e7, alt_mm, relative_mm, 0, 0, 0, 0
            ),
            "GPS_RAW_INT": mavlink.MAVLink_gps_raw_int_message(
                0, fix if k == drone else 3, lat_e7, lon_e7, gnss_mm, 70, 70, 0, 0, 12
            ),
            "EKF_STATUS_REPORT": mavlink.MAVLink_ekf_status_report_message(
                EKF_NEEDED, 0.1, 0.1, 0.1, 0.1, 0.0
            ),
        })  # fmt: skip
    return sent


def judge(sent: list[dict]):
    return judge_readiness(NAMES, sent, MODEL, HOLDS, ORIGIN, HOME_HEIGHT)


def test_three_drones_holding_as_the_model_assumes_are_ready():
    readiness = judge(reports())
    assert readiness.ready, readiness.reasons
    assert np.allclose(readiness.hold_error, 0.0, atol=0.01)
    assert np.allclose(readiness.altitude_disagreement, 0.0, atol=0.002)


@pytest.mark.parametrize("baro", [0.3, -0.2])
def test_a_drifted_barometer_is_named_with_its_drone_and_its_disagreement(baro: float):
    """The uncalibrated barometer of SITL's stock sensors: its estimate decimetres from the
    GNSS altitude, beyond the model's common vertical bound (0.04 m)."""
    readiness = judge(reports(baro=baro))
    assert readiness.reasons == (
        f"drone 2: estimated altitude {baro:+.3f} m from the GNSS altitude, beyond the "
        f"model's {MODEL.common_vertical:.3f} m",
    )
    assert readiness.altitude_disagreement[1] == pytest.approx(baro, abs=0.002)


def test_a_disagreement_within_the_bound_is_ready():
    assert judge(reports(baro=0.9 * MODEL.common_vertical)).ready


def test_a_fix_worse_than_the_model_and_a_silent_stream_are_named():
    sent = reports(fix=2)
    del sent[2]["GPS_RAW_INT"]
    readiness = judge(sent)
    assert "drone 2: GNSS fix type 2 < 3" in readiness.reasons
    assert "drone 3: no GPS_RAW_INT" in readiness.reasons


def test_a_drone_off_its_hold_stretches_the_formation_and_is_refused():
    """Drone 3's estimate 0.2 m east of its hold: beyond the model's horizontal bounds
    (0.04 + 0.03 m), and its distances to the others 0.1-0.2 m off the plan's."""
    offsets = np.zeros((3, 3))
    offsets[2] = [0.2, 0.0, 0.0]
    readiness = judge(reports(offsets))
    stretched = max(
        abs(np.linalg.norm(HOLDS[2] + offsets[2] - HOLDS[j]) - np.linalg.norm(HOLDS[2] - HOLDS[j]))
        for j in (0, 1)
    )
    assert readiness.hold_error[2] == pytest.approx(0.2, abs=0.01)
    assert readiness.formation_error == pytest.approx(stretched, abs=0.01)
    assert any(r.startswith("drone 3: [0.2, ") for r in readiness.reasons), readiness.reasons
    assert any(r.startswith("the formation is ") for r in readiness.reasons)
