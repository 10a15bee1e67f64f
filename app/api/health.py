"""Liveness and readiness."""

from __future__ import annotations

import logging

from fastapi import APIRouter, Depends, Request
from fastapi.concurrency import run_in_threadpool
from sqlalchemy.orm import Session

from app.api.deps import get_session
from app.api.problems import problems
from app.api.schemas import Health
from app.db.migrate import current_revision, head_revision
from app.db.repositories import ping
from app.errors import Unavailable

router = APIRouter(tags=["health"])
log = logging.getLogger("calf_nurbs.health")


@router.get("/livez", response_model=Health, summary="The process is up")
def livez():
    return {"status": "ok"}


@router.get("/readyz", response_model=Health, summary="The database is reachable and migrated to head, and the job runner can run",
            responses=problems(s503="database_unreachable, migrations_pending or runner_unavailable"))
async def readyz(request: Request, session: Session = Depends(get_session)):
    url = request.app.state.settings.resolved_database_url
    try:
        await run_in_threadpool(ping, session)
        current = await run_in_threadpool(current_revision, url)
    except Exception as exc:
        log.exception("readiness: the database is not reachable")  # the cause goes to the log, not to the client
        raise Unavailable("the database is not reachable", code="database_unreachable") from exc
    problem = request.app.state.runner.problem()
    if problem:
        raise Unavailable(problem, code="runner_unavailable")
    head = head_revision(url)
    if current != head:
        raise Unavailable(f"the database is at revision {current}, the code expects {head}", code="migrations_pending")
    return {"status": "ok", "database": request.app.state.engine_dialect, "revision": current}
