"""Service settings: one pydantic-settings object, read from ``FLYCRANE_*`` variables.

Nothing reads the environment at import time: the application gets its Settings from
:func:`get_settings` (a cached dependency that tests override) or from ``create_app``.

Secure defaults (README "Security"): ``flycrane serve`` listens on 127.0.0.1 only and
answers only requests addressed to a loopback name (a DNS-rebinding page cannot reach it),
with a token every task endpoint asks for it, vehicles are loopback or USB serial devices
unless widened here, and finished tasks are deleted after ``retention_days``.
"""

from __future__ import annotations

import re
from functools import lru_cache
from ipaddress import AddressValueError, IPv4Network, IPv6Address, IPv6Network
from pathlib import Path

from pydantic import AnyHttpUrl, Field, SecretStr, ValidationInfo, field_validator
from pydantic_settings import BaseSettings, SettingsConfigDict
from sqlalchemy.engine import make_url
from sqlalchemy.exc import ArgumentError, NoSuchModuleError

from flycrane.execution import MAX_WORKERS, scheduler_address
from flycrane.quantities import MAX_TIME_BUDGET

#: Networks vehicles may be reached on by default: this machine only.
DEFAULT_UPLOAD_NETWORKS = (IPv4Network("127.0.0.0/8"),)
#: Serial devices vehicles may be on by default: USB adapters and flight controllers (by
#: kernel name or by stable id). Consoles (/dev/tty0, /dev/ttyS0, ...) are not among them.
DEFAULT_UPLOAD_DEVICES = (
    r"/dev/ttyUSB[0-9]+",
    r"/dev/ttyACM[0-9]+",
    r"/dev/serial/by-id/[A-Za-z0-9_.+-]+",
)
#: This machine's own names.
LOOPBACK_HOSTS = ("127.0.0.1", "localhost", "::1")
#: Host names a request may be addressed to by default: loopback only.
DEFAULT_ALLOWED_HOSTS = LOOPBACK_HOSTS
#: What a database URL looks like (in refusals).
DATABASE_URL_EXAMPLE = "postgresql+psycopg://user:password@host/dbname"
#: Shortest token accepted: a guess over HTTP must be hopeless.
MIN_TOKEN_LENGTH = 16


class Settings(BaseSettings):
    """Configuration of the mission service (environment prefix ``FLYCRANE_``)."""

    # A refusal never quotes the value: it may be a token, or a URL with a password.
    model_config = SettingsConfigDict(
        env_prefix="FLYCRANE_", frozen=True, hide_input_in_errors=True
    )

    data_dir: Path = Field(Path("data"), description="database file and artifacts live here")
    database_url: str | None = Field(
        None, description="SQLAlchemy URL; default sqlite:///<data_dir>/flycrane.db"
    )
    database_busy_timeout: float = Field(
        5.0,
        gt=0,
        le=60,
        description="how long a request waits for a locked database before 503 [s]",
    )
    workers: int = Field(1, ge=1, le=MAX_WORKERS, description="planning worker processes")
    executor: str = Field(
        "local",
        description="where tasks run: 'local' (a pool of `workers` processes) or a Dask "
        "cluster, 'dask://host:port' (its scheduler; also tcp://). Its workers "
        "must reach database_url (PostgreSQL, not the local SQLite file); artifacts come back "
        "with the results, no shared disk is assumed",
    )
    max_queued_tasks: int = Field(
        32, ge=1, description="tasks queued or running at once; more are refused with 503"
    )
    max_request_bytes: int = Field(1_000_000, ge=1024, description="largest request body")
    max_time_budget: float = Field(
        600.0,
        gt=0,
        le=MAX_TIME_BUDGET,
        description="largest planner time budget and improve time [s]",
    )
    api_token: SecretStr | None = Field(
        None,
        description="bearer token for every task endpoint (reads too, unless read_token or "
        "public_reads); unset: no authentication (loopback use only)",
    )
    read_token: SecretStr | None = Field(
        None, description="a second token that may only read tasks (needs api_token)"
    )
    public_reads: bool = Field(
        False, description="with api_token set, let anyone read tasks and their artifacts"
    )
    allowed_hosts: tuple[str, ...] = Field(
        DEFAULT_ALLOWED_HOSTS,
        description="Host header values accepted ('*.example.org' patterns; '*': any); "
        "others get 400",
    )
    public_url: AnyHttpUrl | None = Field(
        None,
        description="base of the URLs in responses (behind a reverse proxy); default: the "
        "request's own (an allowed host)",
    )
    retention_days: float | None = Field(
        30.0,
        gt=0,
        le=36_500,
        description="finished tasks older than this are deleted with their files; 'none': kept",
    )
    upload_networks: tuple[IPv4Network | IPv6Network, ...] = Field(
        DEFAULT_UPLOAD_NETWORKS,
        description="networks a vehicle's IP address must be in (addresses only: names are "
        "never resolved)",
    )
    upload_devices: tuple[str, ...] = Field(
        DEFAULT_UPLOAD_DEVICES,
        description="regular expressions a vehicle's serial device path must match whole",
    )
    upload_timeout: float = Field(
        60.0,
        gt=0,
        le=3600,
        description="deadline of a whole upload, for each vehicle: connection, mission "
        "transfer, read-back and parameter reads [s]",
    )
    max_concurrent_uploads: int = Field(
        4, ge=1, le=64, description="uploads running at once; more are refused with 503"
    )
    max_concurrent_statics: int = Field(
        2,
        ge=1,
        le=64,
        description="/v1/statics requests computed at once (each keeps a core of the server "
        "busy); more are refused with 503",
    )
    api_docs: bool = Field(
        True,
        description="serve the API's description, /openapi.json, and its documentation page, "
        "/docs (Swagger UI from this server); false: neither",
    )

    @field_validator("retention_days", mode="before")
    @classmethod
    def _kept(cls, value: object) -> object:
        """``none`` (or empty) keeps finished tasks: an unset variable means the default."""
        if isinstance(value, str) and value.strip().lower() in ("", "none", "null"):
            return None
        return value

    @field_validator("data_dir", mode="before")
    @classmethod
    def _named(cls, value: object) -> object:
        """An empty name would quietly mean the current directory."""
        if isinstance(value, str | Path) and not str(value).strip():
            raise ValueError("an empty name: give the directory (default: data)")
        return value

    @field_validator("allowed_hosts")
    @classmethod
    def _some_host(cls, hosts: tuple[str, ...]) -> tuple[str, ...]:
        if not hosts:
            raise ValueError("no host: every request would get 400; give '*' for any")
        return hosts

    @field_validator("api_token", "read_token")
    @classmethod
    def _strong_token(cls, value: SecretStr | None) -> SecretStr | None:
        """An empty token must not quietly mean "no authentication"."""
        if value is None:
            return None
        token = value.get_secret_value()
        if token.strip() != token or len(token) < MIN_TOKEN_LENGTH:
            raise ValueError(
                f"must be at least {MIN_TOKEN_LENGTH} characters without surrounding "
                "whitespace (unset the variable to run without authentication)"
            )
        return value

    @field_validator("database_url")
    @classmethod
    def _usable_database_url(cls, value: str | None) -> str | None:
        """A URL SQLAlchemy cannot read, or whose database or driver it cannot load, is
        refused here, naming this setting, not with a traceback when the server opens it.
        The reason never quotes the URL (it may hold a password). Empty: the default."""
        if not value:
            return value
        try:
            dialect = make_url(value).get_dialect()
        except (ArgumentError, NoSuchModuleError, ValueError) as error:
            raise ValueError(
                f"not a database URL SQLAlchemy can use ({error}); e.g. {DATABASE_URL_EXAMPLE}"
            ) from None
        url = make_url(value)
        if dialect.name == "sqlite" and url.database in (None, "", ":memory:"):
            raise ValueError(
                "an in-memory SQLite database holds nothing the workers or a restart can "
                "see; name a file (sqlite:////path/flycrane.db) or leave it unset"
            )
        if dialect.is_async:
            raise ValueError(
                f"{dialect.driver} is an asyncio driver, the service needs a synchronous one; "
                f"e.g. {DATABASE_URL_EXAMPLE}"
            )
        try:
            dialect.import_dbapi()
        except ImportError as error:
            raise ValueError(
                f"the {dialect.name} driver {dialect.driver} is not installed ({error})"
            ) from None
        return value

    @field_validator("upload_devices")
    @classmethod
    def _device_patterns(cls, patterns: tuple[str, ...]) -> tuple[str, ...]:
        """Every pattern compiles (as :func:`service.uploads.refusal` uses it): a broken one
        refuses the start instead of failing every upload."""
        for pattern in patterns:
            try:
                re.compile(pattern, re.ASCII)
            except re.error as error:
                raise ValueError(f"{pattern!r} is not a regular expression: {error}") from None
        return patterns

    @field_validator("executor")
    @classmethod
    def _executor_address(cls, value: str) -> str:
        if value != "local":
            try:
                scheduler_address(value)
            except ValueError as error:
                raise ValueError(f"must be 'local' or a Dask scheduler address: {error}") from None
        return value

    @property
    def dask_scheduler(self) -> str | None:
        """The Dask scheduler's address (``tcp://host:port``), None for the local pool."""
        return None if self.executor == "local" else scheduler_address(self.executor)

    @field_validator("read_token")
    @classmethod
    def _read_token_needs_api_token(
        cls, value: SecretStr | None, info: ValidationInfo
    ) -> SecretStr | None:
        if value is not None and info.data.get("api_token") is None:
            raise ValueError("needs FLYCRANE_API_TOKEN: otherwise anyone could write")
        return value

    @property
    def resolved_database_url(self) -> str:
        return self.database_url or f"sqlite:///{self.data_dir / 'flycrane.db'}"

    @property
    def host_patterns(self) -> list[str]:
        """``allowed_hosts`` as a Host header writes them: an IPv6 address in brackets
        (``::1`` -> ``[::1]``, what Starlette's TrustedHostMiddleware compares)."""
        return [_as_in_host_header(host) for host in self.allowed_hosts]

    @property
    def health_host_patterns(self) -> list[str]:
        """The Host header values /healthz answers: ``allowed_hosts`` and this machine's own
        names, so that a health check run beside the server (the Docker image's) passes
        whatever ``allowed_hosts`` says (:class:`service.middleware.TrustedHosts`)."""
        loopback = [_as_in_host_header(host) for host in LOOPBACK_HOSTS]
        return [*self.host_patterns, *(h for h in loopback if h not in self.host_patterns)]

    @property
    def tasks_dir(self) -> Path:
        return self.data_dir / "tasks"

    @property
    def reads_need_token(self) -> bool:
        return self.api_token is not None and not self.public_reads


def _as_in_host_header(host: str) -> str:
    try:
        return f"[{IPv6Address(host.removeprefix('[').removesuffix(']')).compressed}]"
    except AddressValueError:
        return host


@lru_cache
def get_settings() -> Settings:
    """The process's settings, read once from the environment."""
    return Settings()
