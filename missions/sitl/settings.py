"""Where SITL is and how fast it runs: one settings object (environment prefix
``FLYCRANE_SITL_``, e.g. ``FLYCRANE_SITL_BINARY=/opt/ardupilot/arducopter``)."""

from __future__ import annotations

from pathlib import Path

from pydantic import Field
from pydantic_settings import BaseSettings, SettingsConfigDict

#: The project's checkout: SITL is looked for in ``../shared/sitl`` beside it (CI's layout).
PROJECT_ROOT = Path(__file__).resolve().parents[2]


def default_binary() -> Path:
    return PROJECT_ROOT.parent / "shared" / "sitl" / "arducopter"


class SitlSettings(BaseSettings):
    """ArduCopter SITL for flight tests (``../shared/sitl/README.md``)."""

    model_config = SettingsConfigDict(env_prefix="FLYCRANE_SITL_", frozen=True, extra="forbid")

    binary: Path = Field(default_factory=default_binary, description="arducopter SITL build")
    defaults: Path | None = Field(
        None, description="defaults file (default: copter.parm beside the binary)"
    )
    speedup: float = Field(
        2.0,
        gt=0,
        le=50,
        description="simulated seconds per wall second (the host's pauses count this many "
        "times over in the drones' time, and a lost link is judged on at least 0.1 s of wall "
        "time: faster, the team failsafe is slower in the drones' time)",
    )
    boot_speedup: float | None = Field(
        10.0,
        gt=0,
        le=50,
        description="simulated seconds per wall second from the boot to the steady hold "
        "before the release, where the ground reacts to nothing in tenths of a second (None: "
        "speedup); the simulators take speedup for the execution (SIM_SPEEDUP). The "
        "defaults are the suite's: at x5 a 2-core host's pauses stop stream and onboard "
        'flights (BENCHMARKS.md "fly-sitl\'s default speed-up")',
    )
    min_rate: float = Field(
        0.2,
        gt=0,
        le=1,
        description="a flight is refused when a simulator ran slower than this fraction of the "
        "speedup (SYSTEM_TIME against the wall clock): a loaded machine slows the simulators "
        "down, which each vehicle's own clock absorbs, but a near-stall delays the ground's "
        "commands in simulated time",
    )
    boot_timeout: float = Field(
        120.0, gt=0, description="[s wall] until every vehicle has a position estimate"
    )
    calibrated_barometers: bool = Field(
        True,
        description="boot with BARO_GND_TEMP 15 C, the temperature of SITL's atmosphere: it "
        "otherwise converts pressure with a temperature guessed per instance, which reads "
        "heights high and differently on each drone (docs/missions.md)",
    )

    gyro_drift: bool = Field(
        False,
        description="keep SITL's artificial gyro drift (SIM_DRIFT_SPEED, a 10-minute "
        "triangle): the EKF's attitude lags the ramp and every drone holds a few centimetres "
        "off its target, all alike (docs/missions.md); a real gyro's bias settles after "
        "warm-up and the EKF follows it",
    )

    @property
    def defaults_file(self) -> Path:
        return self.defaults or self.binary.parent / "copter.parm"
