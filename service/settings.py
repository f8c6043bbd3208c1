"""Service settings: one pydantic-settings object, read from ``FLYCRANE_*`` variables.

Nothing reads the environment at import time: the application gets its Settings from
:func:`get_settings` (a cached dependency that tests override) or from ``create_app``.
"""

from __future__ import annotations

from functools import lru_cache
from pathlib import Path

from pydantic import Field, field_validator
from pydantic_settings import BaseSettings, SettingsConfigDict

#: Vehicle addresses allowed for upload by default: loopback and serial devices only.
DEFAULT_UPLOAD_ALLOW = (
    r"^(udp|udpin|udpout|tcp|tcpin):(127\.\d+\.\d+\.\d+|localhost|\[?::1\]?):\d+$",
    r"^(serial:)?/dev/tty[A-Za-z0-9_]+(:\d+)?$",
)


class Settings(BaseSettings):
    """Configuration of the mission service (environment prefix ``FLYCRANE_``)."""

    model_config = SettingsConfigDict(env_prefix="FLYCRANE_", frozen=True)

    data_dir: Path = Field(Path("data"), description="database file and artifacts live here")
    database_url: str | None = Field(
        None, description="SQLAlchemy URL; default sqlite:///<data_dir>/flycrane.db"
    )
    workers: int = Field(1, ge=1, le=256, description="planning worker processes")
    max_queued_tasks: int = Field(
        32, ge=1, description="tasks queued or running at once; more are refused with 503"
    )
    max_request_bytes: int = Field(1_000_000, ge=1024, description="largest request body")
    max_time_budget: float = Field(600.0, gt=0, description="largest planner time budget [s]")
    api_token: str | None = Field(
        None, description="bearer token required by mutating endpoints; None: no auth"
    )
    upload_allow: tuple[str, ...] = Field(
        DEFAULT_UPLOAD_ALLOW,
        description="regular expressions; a vehicle address must match one to be uploaded to",
    )
    upload_timeout: float = Field(60.0, gt=0, description="overall upload deadline [s]")

    @field_validator("api_token")
    @classmethod
    def _non_empty_token(cls, value: str | None) -> str | None:
        return value or None

    @property
    def resolved_database_url(self) -> str:
        return self.database_url or f"sqlite:///{self.data_dir / 'flycrane.db'}"

    @property
    def tasks_dir(self) -> Path:
        return self.data_dir / "tasks"


@lru_cache
def get_settings() -> Settings:
    """The process's settings, read once from the environment."""
    return Settings()
