"""The request's context: its id (``X-Request-ID``), its log line, its latency metric.

A pure ASGI middleware (no response buffering: scan uploads stream through it).

- The request id is the client's ``X-Request-ID`` when it is a plain token (letters,
  digits, ``._:-``, at most 128), else a new random one; it is echoed on every response,
  bound to every log line written while the request runs, and carried in every problem
  document (``request_id``) so that a clinic can quote it.
- One log line per request: method, route template, status, duration, tenant.  Not the
  raw query string or any header, and never a body.
- The latency is observed in ``calf_http_request_duration_seconds`` under the route's
  template (``unmatched`` for paths that match no route).
"""

from __future__ import annotations

import re
import time
import uuid

import structlog

REQUEST_ID_HEADER = "x-request-id"
CLIENT_REQUEST_ID = re.compile(r"^[A-Za-z0-9._:-]{1,128}$")
log = structlog.stdlib.get_logger("calf_nurbs.http")


def request_id_of(scope) -> str | None:
    return scope.get("state", {}).get("request_id")


class RequestContextMiddleware:
    def __init__(self, app, metrics):
        self.app = app
        self.metrics = metrics

    async def __call__(self, scope, receive, send):
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return
        incoming = dict(scope.get("headers") or []).get(REQUEST_ID_HEADER.encode(), b"").decode("latin-1")
        request_id = incoming if CLIENT_REQUEST_ID.match(incoming) else uuid.uuid4().hex
        scope.setdefault("state", {})["request_id"] = request_id
        structlog.contextvars.clear_contextvars()
        structlog.contextvars.bind_contextvars(request_id=request_id)
        started = time.perf_counter()
        status = 500

        async def send_with_id(message):
            nonlocal status
            if message["type"] == "http.response.start":
                status = message["status"]
                headers = [(k, v) for k, v in message.get("headers", []) if k.lower() != REQUEST_ID_HEADER.encode()]
                message = {**message, "headers": [*headers, (REQUEST_ID_HEADER.encode(), request_id.encode())]}
            await send(message)

        try:
            await self.app(scope, receive, send_with_id)
        finally:
            seconds = time.perf_counter() - started
            route = getattr(scope.get("route"), "path", None) or "unmatched"
            self.metrics.request_seconds.labels(scope["method"], route, str(status)).observe(seconds)
            log.info("request", method=scope["method"], route=route, status=status,
                     duration_ms=round(1000 * seconds, 1), tenant=scope["state"].get("tenant_id"))
            structlog.contextvars.clear_contextvars()
