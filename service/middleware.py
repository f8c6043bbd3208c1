"""ASGI middleware of the service: the allowed Host names (400), the request-body limit (413)
enforced on the bytes, JSON request bodies only (415), and the security headers of every
response (:mod:`service.security`)."""

from __future__ import annotations

from collections.abc import Sequence

from starlette.datastructures import MutableHeaders
from starlette.middleware.trustedhost import TrustedHostMiddleware
from starlette.responses import JSONResponse
from starlette.types import ASGIApp, Message, Receive, Scope, Send

from service.security import CSP, HEADERS, NOTHING


class SecurityHeaders:
    """Add :data:`service.security.HEADERS` to every response, and the policy
    :data:`~service.security.NOTHING` to those whose route set none (installed outermost,
    so that the refusals of the other middleware get them too)."""

    def __init__(self, app: ASGIApp) -> None:
        self.app = app

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return

        async def hardened(message: Message) -> None:
            if message["type"] == "http.response.start":
                headers = MutableHeaders(scope=message)
                for name, value in HEADERS.items():
                    headers[name] = value
                if CSP not in headers:
                    headers[CSP] = NOTHING
            await send(message)

        await self.app(scope, receive, hardened)


class TrustedHosts:
    """Refuse requests addressed to a host name other than ``allowed_hosts`` with 400
    (Starlette's TrustedHostMiddleware), but let ``GET /healthz`` be addressed to
    ``health_hosts`` too: this machine's own names (``Settings.health_host_patterns``), so
    that a health check run beside the server, such as the Docker image's on
    ``http://127.0.0.1:8000/healthz``, passes when ``allowed_hosts`` names only the public
    host a proxy forwards.

    This opens no way in to DNS rebinding: a page that rebinds its own name to this machine
    sends that name as Host, never a loopback one, and a page's request to a loopback name is
    cross-origin, so it cannot read the answer. Nor does /healthz put the Host in what it
    answers (no URLs) or hold task data; it is open without a token anyway.
    """

    HEALTH_PATH = "/healthz"

    def __init__(
        self, app: ASGIApp, allowed_hosts: Sequence[str], health_hosts: Sequence[str]
    ) -> None:
        self.checked = TrustedHostMiddleware(app, allowed_hosts=allowed_hosts)
        self.health = TrustedHostMiddleware(app, allowed_hosts=health_hosts)

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        health = (
            scope["type"] == "http"
            and scope["method"] == "GET"
            and scope["path"] == self.HEALTH_PATH
        )
        await (self.health if health else self.checked)(scope, receive, send)


class BodySizeLimit:
    """Refuse request bodies above ``limit`` bytes with 413.

    Counts the bytes as they arrive, so a missing or lying Content-Length (a chunked body)
    does not help. Once the limit is crossed the 413 is sent at once, the application is
    told the client left, and whatever it answers is dropped.
    """

    def __init__(self, app: ASGIApp, limit: int) -> None:
        self.app, self.limit = app, limit

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return
        declared = dict(scope.get("headers", [])).get(b"content-length")
        if declared is not None and declared.isdigit() and int(declared) > self.limit:
            await self._refuse(scope, receive, send)
            return
        seen, refused, started = 0, False, False

        async def counting() -> Message:
            nonlocal seen, refused
            if refused:
                return {"type": "http.disconnect"}
            message = await receive()
            seen += len(message.get("body", b""))
            if seen > self.limit:
                refused = True
                if not started:
                    await self._refuse(scope, receive, send)
                return {"type": "http.disconnect"}
            return message

        async def guarded(message: Message) -> None:
            nonlocal started
            if refused:
                return
            started = True
            await send(message)

        await self.app(scope, counting, guarded)

    async def _refuse(self, scope: Scope, receive: Receive, send: Send) -> None:
        detail = {"detail": f"request body larger than {self.limit} bytes"}
        refusal = JSONResponse(detail, status_code=413, headers={"connection": "close"})
        await refusal(scope, receive, send)


def _content_type_refusal(headers: list[tuple[bytes, bytes]]) -> str | None:
    """Why a request's Content-Type headers are not ``application/json``, or None."""
    types = [value.decode("latin-1") for name, value in headers if name == b"content-type"]
    if not types:
        return "header Content-Type is missing"
    for value in types:
        if value.split(";", 1)[0].strip().lower() != "application/json":
            return f"header Content-Type is {value[:100]!r}"
    return None


class JsonBodiesOnly:
    """Refuse POST, PUT and PATCH requests whose Content-Type is not ``application/json``
    (parameters such as ``; charset=utf-8`` allowed) with 415.

    A page on another site can make a browser POST text/plain, form-encoded or multipart
    bodies, or none, here without asking first (a CORS "simple request"); a JSON body needs
    the preflight, which this server never grants.
    """

    METHODS = frozenset({"POST", "PUT", "PATCH"})

    def __init__(self, app: ASGIApp) -> None:
        self.app = app

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] == "http" and scope["method"] in self.METHODS:
            reason = _content_type_refusal(scope["headers"])
            if reason is not None:
                detail = f"{reason}: this API takes JSON bodies, Content-Type: application/json"
                await JSONResponse({"detail": detail}, status_code=415)(scope, receive, send)
                return
        await self.app(scope, receive, send)
