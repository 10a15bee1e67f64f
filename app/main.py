"""The FastAPI application: ``app = create_app()``; run with ``calf-nurbs serve``."""

from __future__ import annotations

import asyncio
import logging
from contextlib import asynccontextmanager

from fastapi import FastAPI
from fastapi.middleware.cors import CORSMiddleware
from fastapi.openapi.utils import get_openapi

from app import __version__
from app.api import cases, comparisons, designs, health, jobs, metrics, populations, records, scans, size_charts, web
from app.api.guard import HeadAsGetMiddleware, RequestGuardMiddleware
from app.api.middleware import RequestContextMiddleware
from app.api.problems import add_problem_schema, install_problem_handlers
from app.db.session import engine_for, session_factory
from app.jobs.runner import EmbeddedRunner
from app.metrics import Metrics
from app.services.fair_share import CheckGate
from app.services.health import wait_for_database
from app.services.rate_limits import RateLimiter
from app.services.storage import ScanStore
from app.settings import Settings, get_settings

log = logging.getLogger("calf_nurbs")
#: at start-up, temporary uploads of dead processes of this host are removed, and any
#: older than this (another host's process cannot be asked; an upload takes minutes)
TEMP_MAX_AGE_S = 3600.0
TEMP_SWEEP_S = 600.0

DESCRIPTION = """Turns 3D scans of legs into compact, exact NURBS models of the calf
(Li et al., *Fast NURBS-based parametric modeling of human calves*), and serves the
surface, its measurements and graduated compression stocking designs.

Every `/api/v1` request carries the clinic's API key (`Authorization: Bearer <key>` or
`X-API-Key: <key>`); a clinic sees only its own scans, jobs, records and designs.
Upload a scan (`POST /api/v1/scans`), poll the job it returns, then fetch the record,
its surface (STL / GLB / glTF in the scan's own coordinates) and its measurements.
Every error is an RFC 9457 `application/problem+json` document whose `type` ends in a
stable code. Lengths are millimetres."""


async def _sweep_temp(store: ScanStore) -> None:
    """Every TEMP_SWEEP_S: the temporary uploads of processes that died since start-up
    (another API process of this host, killed mid-upload) are removed without waiting
    for a restart."""
    while True:
        await asyncio.sleep(TEMP_SWEEP_S)
        try:
            removed = await asyncio.to_thread(store.clean_temp, TEMP_MAX_AGE_S)
        except OSError:  # the data directory is unavailable for a moment: next round
            continue
        if removed:
            log.warning("removed %d temporary upload file(s) left by an interrupted process", removed)


def _broker_send(settings: Settings):
    """Dramatiq's send, when a broker is configured (imported only then)."""
    if not settings.broker_url:
        return None
    from app.jobs import dramatiq_queue

    return dramatiq_queue.send


def create_app(settings: Settings | None = None) -> FastAPI:
    settings = settings or get_settings()

    @asynccontextmanager
    async def lifespan(app: FastAPI):
        settings.data_dir.mkdir(parents=True, exist_ok=True)
        url = settings.resolved_database_url
        app.state.settings = settings
        app.state.sessions = session_factory(url)
        app.state.engine_dialect = engine_for(url).dialect.name
        app.state.store = ScanStore(settings.scan_dir, settings.tmp_dir, settings.placed_dir)
        app.state.runner = EmbeddedRunner(app.state.sessions, app.state.store, settings.workers, settings.job_timeout_s,
                                          settings.run_jobs, metrics=app.state.metrics, lease_s=settings.job_lease_s,
                                          max_attempts=settings.job_max_attempts, enqueue=_broker_send(settings),
                                          worker_memory_bytes=settings.worker_memory_bytes,
                                          fits_per_tenant=settings.fits_per_tenant)
        await asyncio.to_thread(wait_for_database, app.state.sessions, settings.db_wait_s)
        removed = app.state.store.clean_temp(TEMP_MAX_AGE_S)
        if removed:
            log.warning("removed %d temporary upload file(s) left by an interrupted process", removed)
        if not settings.auth_required:
            log.warning("API keys are not required (CALF_AUTH=off or bound to %s): a request without a key acts "
                        "for the tenant 'default' (a key sent is still checked). Bind to a public address or set "
                        "CALF_AUTH=required to require keys.",
                        settings.host)
        await app.state.runner.start()
        sweeper = asyncio.create_task(_sweep_temp(app.state.store), name="calf-temp-sweeper")
        try:
            yield
        finally:
            sweeper.cancel()
            await app.state.runner.stop()

    docs = settings.api_docs  # off by default: see Settings (CALF_API_DOCS)
    app = FastAPI(title="calf-nurbs", version=__version__, description=DESCRIPTION, lifespan=lifespan,
                  docs_url="/docs" if docs else None, redoc_url="/redoc" if docs else None)
    app.state.metrics = Metrics()
    app.state.check_gate = CheckGate(settings.checks_per_tenant, settings.validation_timeout_s)
    app.state.rate_limits = {
        "requests": RateLimiter(settings.rate_limit, settings.rate_burst),
        "uploads": RateLimiter(settings.upload_rate_limit, settings.upload_rate_burst),
    }
    install_problem_handlers(app)
    if settings.cors_origins:
        # browsers of the listed origins only (a clinic's portal); the headers a client
        # needs to read: the record's ETag, a job's Location, a 429's Retry-After
        app.add_middleware(
            CORSMiddleware,
            allow_origins=settings.cors_origins,
            allow_methods=["GET", "POST", "DELETE"],
            allow_headers=["Authorization", "X-API-Key", "Content-Type", "Idempotency-Key", "If-None-Match", "Accept"],
            expose_headers=["ETag", "Location", "Retry-After", "X-Request-ID"],
            max_age=600,
        )
    # size and key checked from the headers, before any body is read (inside the request id)
    app.add_middleware(RequestGuardMiddleware)
    # outermost: every response (CORS preflights and problems too) carries the request id
    app.add_middleware(RequestContextMiddleware, metrics=app.state.metrics)
    for module in (scans, jobs, records, cases, comparisons, populations, designs, size_charts, health, metrics, web):
        app.include_router(module.router)
    app.mount("/web", web.static_files(), name="web")
    app.add_middleware(web.SecurityHeadersMiddleware)
    app.add_middleware(HeadAsGetMiddleware)

    def openapi() -> dict:
        if app.openapi_schema is None:
            schema = get_openapi(title=app.title, version=app.version, description=app.description, routes=app.routes)
            app.openapi_schema = add_problem_schema(schema)
        return app.openapi_schema

    app.openapi = openapi  # type: ignore[method-assign]
    return app


app = create_app()
