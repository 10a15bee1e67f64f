"""A case (the clinic's pseudonymous case reference): its records, and its erasure."""

from __future__ import annotations

from dataclasses import asdict

from fastapi import APIRouter, Depends, Path
from sqlalchemy.orm import Session

from app.api.auth import authorize
from app.api.deps import get_session, get_store
from app.api.problems import auth_problems, problems
from app.api.schemas import ErasureOut
from app.services.cases import CASE_REF_PATTERN
from app.services.erasure import ErasureService
from app.services.keys import Principal
from app.services.storage import ScanStore

router = APIRouter(prefix="/api/v1", tags=["cases"], responses=auth_problems())


@router.delete(
    "/cases/{case_ref}",
    response_model=ErasureOut,
    summary="Erase a case: its records (fitted or imported), jobs, designs, idempotent answers, and every scan only "
            "this case used with its stored file, in one transaction (list a case's records with GET "
            "/api/v1/records?case_ref=)",
    responses=problems(s404="case_not_found", s409="job_running: a fit of the case is running; erase it after",
                       s422="invalid_case_ref"),
)
def erase_case(case_ref: str = Path(..., pattern=CASE_REF_PATTERN, description="the case reference"),
               session: Session = Depends(get_session), store: ScanStore = Depends(get_store),
               principal: Principal = Depends(authorize("upload"))):
    return asdict(ErasureService(session, principal.tenant_id, store).erase_case(case_ref))
