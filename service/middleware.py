"""ASGI middleware of the service: the request-body limit (413) enforced on the bytes, JSON
request bodies only (415), and the security headers of every response
(:mod:`service.security`)."""

from __future__ import annotations

from starlette.datastructures import MutableHeaders
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
