"""Populations of calves: the average calf, its modes of variation, girth percentiles."""

from __future__ import annotations

from fastapi import APIRouter, Body, Depends, Request
from fastapi.concurrency import run_in_threadpool
from fastapi.encoders import jsonable_encoder
from fastapi.responses import JSONResponse
from sqlalchemy.orm import Session

from app.api.auth import authorize
from app.api.deps import get_session, get_store
from app.api.problems import auth_problems, problems
from app.api.schemas import PopulationOut, PopulationRequest
from app.services.keys import Principal
from app.services.populations import PopulationService
from app.services.storage import ScanStore

router = APIRouter(prefix="/api/v1", tags=["populations"], responses=auth_problems())


@router.post(
    "/populations",
    status_code=201,
    response_model=PopulationOut,
    summary="A population of records: the average calf (stored as a record), the main modes of variation and "
            "the girth percentiles at B, B1, C, D",
    responses={201: {"description": "Created; Location points at the average calf's record",
                     "headers": {"Location": {"schema": {"type": "string"}}}},
               **problems(s400="bad_request: the body is not UTF-8 JSON", s404="record_not_found",
                          s422="invalid_population (2-200 distinct records), not_lsq (a record that is not an lsq "
                               "record and has no stored scan to refit, or whose refit failed), invalid_option (grid), "
                               "invalid_request")},
)
async def create_population(
    request: Request,
    body: PopulationRequest = Body(...),
    session: Session = Depends(get_session),
    store: ScanStore = Depends(get_store),
    principal: Principal = Depends(authorize("upload")),
):
    service = PopulationService(session, principal.tenant_id, store)
    result = await run_in_threadpool(service.create, body.record_ids, body.grid)
    session.commit()
    return JSONResponse(jsonable_encoder(result), status_code=201, headers={"Location": result["links"]["average"]})
