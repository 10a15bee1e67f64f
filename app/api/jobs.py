"""GET /api/v1/jobs/{id}."""

from __future__ import annotations

from fastapi import APIRouter, Depends
from sqlalchemy.orm import Session

from app.api.auth import authorize
from app.api.deps import get_session
from app.api.problems import auth_problems, problems
from app.api.schemas import JobOut
from app.services.jobs import JobService, job_view
from app.services.keys import Principal

router = APIRouter(prefix="/api/v1", tags=["jobs"], responses=auth_problems())


@router.get("/jobs/{job_id}", response_model=JobOut, summary="A fitting job: status, timings, failure reason, record",
            responses=problems(s404="job_not_found"))
def get_job(job_id: str, session: Session = Depends(get_session), principal: Principal = Depends(authorize("read", "upload"))):
    job, scan = JobService(session, principal.tenant_id).get(job_id)
    return job_view(job, scan)
