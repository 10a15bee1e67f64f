"""Liveness and readiness (public, for load balancers: the details - database kind and
migration revision - only for an operator key, or with keys off)."""

from __future__ import annotations

from fastapi import APIRouter, Depends, Request
from fastapi.concurrency import run_in_threadpool
from sqlalchemy.orm import Session

from app.api.auth import optional_principal
from app.api.deps import get_session
from app.api.problems import problems
from app.api.schemas import Health
from app.services.health import readiness

router = APIRouter(tags=["health"])


@router.get("/livez", response_model=Health, response_model_exclude_none=True, summary="The process is up")
def livez():
    return {"status": "ok"}


@router.get("/readyz", response_model=Health, response_model_exclude_none=True,
            summary="The database is reachable and migrated to head, and the job runner can run",
            responses=problems(s503="database_unreachable, migrations_pending or runner_unavailable"))
async def readyz(request: Request, session: Session = Depends(get_session)):
    revision = await run_in_threadpool(readiness, session, request.app.state.settings.resolved_database_url,
                                       request.app.state.runner.problem())
    principal = await run_in_threadpool(optional_principal, request, session)
    if principal is None or not principal.allows("operator"):
        return {"status": "ok"}
    return {"status": "ok", "database": request.app.state.engine_dialect, "revision": revision}
