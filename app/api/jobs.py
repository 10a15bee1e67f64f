"""GET /api/v1/jobs/{id}; GET /api/v1/usage: the clinic's own queue and limits."""

from __future__ import annotations

from fastapi import APIRouter, Depends, Request
from sqlalchemy.orm import Session

from app.api.auth import authorize
from app.api.deps import get_session
from app.api.problems import auth_problems, problems
from app.api.schemas import JobOut, UsageOut
from app.services.jobs import JobService
from app.services.keys import Principal

router = APIRouter(prefix="/api/v1", tags=["jobs"], responses=auth_problems())


@router.get("/jobs/{job_id}", response_model=JobOut, summary="A fitting job: status, timings, failure reason, record",
            responses=problems(s404="job_not_found"))
def get_job(job_id: str, session: Session = Depends(get_session), principal: Principal = Depends(authorize("read", "upload"))):
    return JobService(session, principal.tenant_id).view(job_id)


@router.get("/usage", response_model=UsageOut, summary="Your clinic's jobs by status and the fair-share limits that apply")
def get_usage(request: Request, session: Session = Depends(get_session),
              principal: Principal = Depends(authorize("read", "upload"))):
    settings = request.app.state.settings
    return JobService(session, principal.tenant_id).usage(settings)
