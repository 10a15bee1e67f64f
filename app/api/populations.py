"""Populations of calves: the average calf, its modes of variation, girth percentiles."""

from __future__ import annotations

from fastapi import APIRouter, Body, Depends, Request, Response
from fastapi.concurrency import run_in_threadpool
from sqlalchemy.orm import Session

from app.api.auth import authorize
from app.api.deps import get_runner, get_session, get_store
from app.api.problems import auth_problems, problems
from app.api.schemas import PopulationOut, PopulationRefitting, PopulationRequest
from app.jobs.runner import EmbeddedRunner
from app.services.keys import Principal
from app.services.populations import PopulationService, Refitting
from app.services.storage import ScanStore

router = APIRouter(prefix="/api/v1", tags=["populations"], responses=auth_problems())


@router.post(
    "/populations",
    status_code=201,
    response_model=PopulationOut | PopulationRefitting,
    summary="A population of records: the average calf (stored as a record), the main modes of variation and "
            "the girth percentiles at B, B1, C, D",
    description="Records that are not lsq records on the grid are refitted in mode lsq on their stored scans by "
                "fit jobs: while those run the answer is 202 with the jobs (and Retry-After); the same request "
                "made again once they have succeeded makes the population (201).",
    responses={201: {"description": "Created; Location points at the average calf's record",
                     "headers": {"Location": {"schema": {"type": "string"}}}},
               202: {"model": PopulationRefitting,
                     "description": "Some records are being refitted in mode lsq: make the same request again later",
                     "headers": {"Retry-After": {"schema": {"type": "integer"}}}},
               **problems(s400="bad_request: the body is not UTF-8 JSON", s404="record_not_found",
                          s422="invalid_population (2-200 distinct records), not_lsq (a record that is not an lsq "
                               "record and has no stored scan to refit, or whose refit failed), invalid_option (grid), "
                               "invalid_request")},
)
async def create_population(
    request: Request,
    response: Response,
    body: PopulationRequest = Body(...),
    session: Session = Depends(get_session),
    store: ScanStore = Depends(get_store),
    runner: EmbeddedRunner = Depends(get_runner),
    principal: Principal = Depends(authorize("upload")),
):
    service = PopulationService(session, principal.tenant_id, store, request.app.state.settings.tenant_max_jobs)
    result = await run_in_threadpool(service.create, body.record_ids, body.grid)
    session.commit()
    if isinstance(result, Refitting):
        for job_id in result.new_job_ids:  # after the commit: a worker never sees an uncommitted job
            await runner.submitted(job_id)
        view = result.view()
        response.status_code = 202
        response.headers["Retry-After"] = str(view["retry_after_s"])
        return view
    response.headers["Location"] = result["links"]["average"]
    return result
