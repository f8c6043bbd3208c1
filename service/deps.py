"""Shared dependencies of the routes: settings, store, jobs, metrics, authentication."""

from __future__ import annotations

import hmac
from dataclasses import dataclass

from fastapi import Depends, Request
from fastapi.security import HTTPAuthorizationCredentials, HTTPBearer

from service.errors import UnauthorizedError
from service.jobs import JobManager
from service.metrics import ServiceMetrics
from service.settings import Settings
from service.storage import TaskStore


@dataclass
class ServiceState:
    """What one application instance holds (created in ``create_app``'s lifespan)."""

    settings: Settings
    store: TaskStore
    jobs: JobManager
    metrics: ServiceMetrics


def get_state(request: Request) -> ServiceState:
    return request.app.state.service


_bearer = HTTPBearer(auto_error=False)


def require_token(
    state: ServiceState = Depends(get_state),
    credentials: HTTPAuthorizationCredentials | None = Depends(_bearer),
) -> None:
    """Mutating endpoints need ``Authorization: Bearer <token>`` when a token is set."""
    expected = state.settings.api_token
    if expected is None:
        return
    given = credentials.credentials if credentials else ""
    if not hmac.compare_digest(given.encode(), expected.encode()):
        raise UnauthorizedError(
            "a valid bearer token is required for this endpoint",
            headers={"WWW-Authenticate": "Bearer"},
        )
