"""Checks made before a request's body is read: its size and its API key.

FastAPI reads and parses a JSON body before it resolves a route's dependencies, so an
API key checked by a dependency is checked after the body has been received and
parsed: an unauthenticated client could make the server read a 100 MB body.  This pure
ASGI middleware answers first, from the headers alone, for every ``/api/v1`` request
that may carry a body (POST, PUT, PATCH):

- a ``Content-Length`` above the route's limit is refused with 413 at once (uploads:
  CALF_MAX_UPLOAD_MB; every JSON body: CALF_MAX_JSON_KB), a malformed one with 400;
- with keys required, the key is authenticated (in a worker thread: it is a database
  lookup) and a missing or invalid key answered 401 before a byte of the body is read;
  the principal is handed to the route's :func:`app.api.auth.authorize` dependency in
  the request's scope, so it is looked up once;
- a body sent without a length (chunked) is counted as it arrives and cut off with 413
  past the limit.

With the JSON limit the event loop never parses more than CALF_MAX_JSON_KB (1 MiB by
default: the largest record the service makes, an lsq record on the 40 x 72 grid, is
about 200 kB of JSON).
"""

from __future__ import annotations

import anyio
from starlette.exceptions import HTTPException
from starlette.requests import Request

from app.api.problems import problem_response
from app.errors import PayloadTooLarge, ServiceError, Unauthorized
from app.services.keys import KeyService

API_PREFIX = "/api/v1"
BODY_METHODS = ("POST", "PUT", "PATCH")
#: the one route whose body is a scan (counted against CALF_MAX_UPLOAD_MB)
UPLOAD_PATHS = ("/api/v1/scans",)
PRINCIPAL_STATE = "principal"


def presented_key(headers: dict[bytes, bytes]) -> str | None:
    """The API key of ``Authorization: Bearer <key>`` or ``X-API-Key: <key>``."""
    authorization = headers.get(b"authorization", b"").decode("latin-1").strip()
    scheme, _, credentials = authorization.partition(" ")
    if scheme.lower() == "bearer" and credentials.strip():
        return credentials.strip()
    key = headers.get(b"x-api-key", b"").decode("latin-1").strip()
    return key or None


def _authenticate(sessions, key: str):
    with sessions() as session:
        return KeyService(session).authenticate(key)


class RequestGuardMiddleware:
    def __init__(self, app):
        self.app = app

    async def __call__(self, scope, receive, send):
        if scope["type"] != "http" or scope["method"] not in BODY_METHODS or not scope["path"].startswith(API_PREFIX):
            return await self.app(scope, receive, send)
        settings = scope["app"].state.settings
        limit = settings.max_upload_bytes if scope["path"] in UPLOAD_PATHS else settings.max_json_bytes
        what = "an upload" if scope["path"] in UPLOAD_PATHS else "a JSON body"
        headers = dict(scope.get("headers") or [])
        try:
            declared = headers.get(b"content-length")
            if declared is not None:
                text = declared.decode("latin-1").strip()
                if not text.isdigit():
                    raise ServiceError(f"Content-Length must be a number of bytes, not {text[:40]!r}",
                                       code="invalid_content_length")
                if int(text) > limit:
                    raise PayloadTooLarge(f"the request declares {int(text)} bytes; {what} may have at most {limit} "
                                          "bytes here", extra={"limit_bytes": limit})
            key = presented_key(headers)
            if settings.auth_required and key is None:
                raise Unauthorized("this service needs your clinic's API key: send it as 'Authorization: Bearer "
                                   "<key>' or 'X-API-Key: <key>'", code="missing_key")
            if key is not None:  # auth off too: a key sent is a key checked (app.api.auth)
                principal = await anyio.to_thread.run_sync(_authenticate, scope["app"].state.sessions, key)
                scope.setdefault("state", {})[PRINCIPAL_STATE] = principal
        except ServiceError as error:
            response = problem_response(Request(scope), error.status, error.code, error.title, error.detail, error.extra)
            response.headers.update(error.headers)
            return await response(scope, receive, send)
        if scope["path"] in UPLOAD_PATHS:  # the upload counts its own bytes (app.services.uploads)
            return await self.app(scope, receive, send)
        received = 0

        async def counted_receive():
            nonlocal received
            message = await receive()
            if message["type"] == "http.request":
                received += len(message.get("body", b""))
                if received > limit:
                    raise HTTPException(413, f"the request body exceeds {limit} bytes, the most {what} may have here")
            return message

        await self.app(scope, counted_receive, send)


class HeadAsGetMiddleware:
    """HEAD on every GET route (RFC 9110 9.3.2): answered as the GET would be - status
    and headers, Content-Length included - without the body.  FastAPI's routes answer
    only the methods they declare; the static files answer HEAD themselves."""

    def __init__(self, app):
        self.app = app

    async def __call__(self, scope, receive, send):
        if scope["type"] != "http" or scope["method"] != "HEAD" or scope["path"].startswith("/web/"):
            return await self.app(scope, receive, send)

        async def send_headers_only(message):
            if message["type"] == "http.response.body":
                if message.get("more_body", False):
                    return
                message = {"type": "http.response.body", "body": b"", "more_body": False}
            await send(message)

        await self.app({**scope, "method": "GET"}, receive, send_headers_only)
