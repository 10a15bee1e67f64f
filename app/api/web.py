"""The web workbench: a single-page app served from app/web at / (static files; its
only library, three.js, is vendored under app/web/vendor, so nothing comes from a CDN:
clinics run the service on closed networks and the data is health data).

Every response of the service (but the interactive API docs, off unless CALF_API_DOCS)
carries a strict Content-Security-Policy: scripts,
styles, images and connections from this origin only (no inline script, no eval, no
third party), no plugins, no framing; WebGL needs nothing more.
"""

from __future__ import annotations

from pathlib import Path

from fastapi import APIRouter
from fastapi.responses import FileResponse
from fastapi.staticfiles import StaticFiles

WEB_DIR = Path(__file__).resolve().parents[1] / "web"
CONTENT_SECURITY_POLICY = (
    "default-src 'none'; script-src 'self'; style-src 'self'; img-src 'self' data: blob:; "
    "connect-src 'self'; font-src 'self'; base-uri 'none'; form-action 'self'; frame-ancestors 'none'; "
    "object-src 'none'"
)
SECURITY_HEADERS = [
    (b"content-security-policy", CONTENT_SECURITY_POLICY.encode()),
    (b"x-content-type-options", b"nosniff"),
    (b"referrer-policy", b"no-referrer"),
    (b"x-frame-options", b"DENY"),
]

#: FastAPI's interactive API docs load Swagger UI / ReDoc from their CDN with an inline
#: script: they keep the framework's own headers (they are not the workbench, and on a
#: closed network they do not load at all; openapi/openapi.json is the contract)
INTERACTIVE_DOCS = ("/docs", "/redoc")

router = APIRouter(include_in_schema=False)


@router.get("/")
def index() -> FileResponse:
    """The workbench's page (every screen is a client of /api/v1)."""
    return FileResponse(WEB_DIR / "index.html", media_type="text/html", headers={"Cache-Control": "no-cache"})


def static_files() -> StaticFiles:
    return StaticFiles(directory=WEB_DIR)


#: responses that may carry health data (records, scans' points, designs, jobs) or the
#: service's state are never stored by a browser or a proxy
NO_STORE_PREFIXES = ("/api/", "/metrics", "/readyz")


class SecurityHeadersMiddleware:
    """Adds :data:`SECURITY_HEADERS` to every HTTP response, and ``Cache-Control:
    no-store`` to those under :data:`NO_STORE_PREFIXES` (pure ASGI)."""

    def __init__(self, app):
        self.app = app

    async def __call__(self, scope, receive, send):
        if scope["type"] != "http" or scope.get("path", "").startswith(INTERACTIVE_DOCS):
            return await self.app(scope, receive, send)

        added = SECURITY_HEADERS + ([(b"cache-control", b"no-store")] if scope.get("path", "").startswith(NO_STORE_PREFIXES) else [])

        async def send_with_headers(message):
            if message["type"] == "http.response.start":
                names = {name for name, _ in added}
                kept = [(k, v) for k, v in message.get("headers", []) if k.lower() not in names]
                message = {**message, "headers": [*kept, *added]}
            await send(message)

        await self.app(scope, receive, send_with_headers)
