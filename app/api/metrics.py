"""GET /metrics: the process's Prometheus metrics (app.metrics).

With keys required it needs an ``operator`` key - the service operator's, not a
clinic's (Prometheus sends it with ``authorization: {credentials: <key>}`` in its
scrape config): the counts are every clinic's, which is no clinic's business.  Labels
hold no tenant or patient.  A clinic sees its own queue at ``GET /api/v1/usage``.
"""

from __future__ import annotations

from fastapi import APIRouter, Depends, Request, Response
from fastapi.concurrency import run_in_threadpool
from sqlalchemy.orm import Session

from app.api.auth import authorize
from app.api.deps import get_session
from app.api.problems import auth_problems
from app.services.jobs import job_status_counts
from app.services.keys import Principal

router = APIRouter(tags=["health"])


@router.get("/metrics", summary="Prometheus metrics: request latency, upload checks, fit duration, job outcomes",
            response_class=Response,
            responses={200: {"content": {"text/plain": {"schema": {"type": "string"}}},
                             "description": "Prometheus text exposition format 0.0.4"}, **auth_problems()})
async def metrics(request: Request, session: Session = Depends(get_session), principal: Principal = Depends(authorize("operator"))):
    counts = await run_in_threadpool(job_status_counts, session)
    body = request.app.state.metrics.render(counts)
    return Response(body, media_type=request.app.state.metrics.content_type)
