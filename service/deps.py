"""Shared dependencies of the routes: settings, store, jobs, metrics, authentication.

They do no blocking work, so they are coroutines: FastAPI runs them on the event loop, never
waiting for a thread of its pool (which busy requests may all hold; /healthz must answer).
"""

from __future__ import annotations

import hmac
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from typing import Annotated

from fastapi import Depends, Request
from fastapi.security import HTTPAuthorizationCredentials, HTTPBearer
from pydantic import SecretStr

from service.errors import UnauthorizedError
from service.jobs import JobManager
from service.limits import Slots
from service.metrics import ServiceMetrics
from service.settings import Settings
from service.storage import TaskStore
from service.uploads import UploadRunner


@dataclass
class ServiceState:
    """What one application instance holds (created in ``create_app``'s lifespan)."""

    settings: Settings
    store: TaskStore
    jobs: JobManager
    metrics: ServiceMetrics
    uploads: UploadRunner
    #: /v1/statics requests computed at once (``max_concurrent_statics``).
    statics: Slots
    #: The health check's own thread: it answers when every request thread is busy.
    health: ThreadPoolExecutor


async def get_state(request: Request) -> ServiceState:
    return request.app.state.service


#: The application's state, as a route's parameter: ``state: StateDep``.
StateDep = Annotated[ServiceState, Depends(get_state)]


_bearer = HTTPBearer(auto_error=False)
Credentials = Annotated[HTTPAuthorizationCredentials | None, Depends(_bearer)]


def _matches(credentials: HTTPAuthorizationCredentials | None, *tokens: SecretStr) -> bool:
    given = (credentials.credentials if credentials else "").encode()
    # Every token is compared (in constant time each): no early exit says which one is set.
    matched = [hmac.compare_digest(given, t.get_secret_value().encode()) for t in tokens]
    return any(matched)


def _refuse(what: str) -> UnauthorizedError:
    return UnauthorizedError(
        f"a valid bearer token is required to {what}", headers={"WWW-Authenticate": "Bearer"}
    )


async def require_token(
    state: StateDep,
    credentials: Credentials,
) -> None:
    """Changing anything needs ``Authorization: Bearer <api_token>`` when a token is set."""
    token = state.settings.api_token
    if token is not None and not _matches(credentials, token):
        raise _refuse("change tasks")


async def require_reader(
    state: StateDep,
    credentials: Credentials,
) -> None:
    """Reading tasks needs the api_token or the read_token when a token is set (unless
    ``public_reads``): missions carry positions and the logs a whole flight plan."""
    settings = state.settings
    if not settings.reads_need_token or settings.api_token is None:
        return
    tokens = [t for t in (settings.api_token, settings.read_token) if t is not None]
    if not _matches(credentials, *tokens):
        raise _refuse("read tasks")


async def base_url(request: Request, state: StateDep) -> str:
    """Where URLs in responses start: ``public_url`` behind a proxy, else the request's own
    base (its Host is one of ``allowed_hosts``, checked before any route runs)."""
    configured = state.settings.public_url
    if configured is not None:
        return str(configured).rstrip("/") + "/"
    return str(request.base_url)


#: Where URLs in responses start, as a route's parameter: ``base: BaseUrl``.
BaseUrl = Annotated[str, Depends(base_url)]

#: Route dependencies: reading needs :func:`require_reader`, changing :func:`require_token`.
READ = [Depends(require_reader)]
WRITE = [Depends(require_token)]
