"""Two records of one leg compared over time: girths, volume change, difference map."""

from __future__ import annotations

from typing import Literal

from fastapi import APIRouter, Depends, Query, Request, Response
from fastapi.concurrency import run_in_threadpool
from sqlalchemy.orm import Session

from app.api.auth import authorize
from app.api.deps import get_session
from app.api.negotiation import negotiate
from app.api.problems import auth_problems, problems
from app.api.schemas import ComparisonOut
from app.services.comparisons import ComparisonService
from app.services.keys import Principal

router = APIRouter(prefix="/api/v1", tags=["records"], responses=auth_problems())

MEDIA = {"json": "application/json", "glb": "model/gltf-binary", "csv": "text/csv"}


@router.get(
    "/records/{record_a}/compare/{record_b}",
    response_model=ComparisonOut,
    summary="Record b against record a of the same leg: girths every 5 mm, volume change between B and D, "
            "and a signed difference map (GLB with vertex colours, or CSV)",
    responses={200: {"content": {"model/gltf-binary": {}, "text/csv": {}},
                     "description": "JSON; or the difference map with ?format=glb|csv or Accept"},
               **problems(s404="record_not_found", s406="not_acceptable",
                          s422="different_legs (a left and a right leg), invalid_alignment, no_overlap "
                               "(the aligned calves share less than 20 mm), invalid_record")},
)
async def compare_records(
    record_a: str,
    record_b: str,
    request: Request,
    align: Literal["B", "B1", "C", "D"] = Query("B", description="the landmark both legs are aligned at; heights "
                                                 "are measured from it"),
    file_format: Literal["json", "glb", "csv"] | None = Query(None, alias="format", description="overrides Accept"),
    session: Session = Depends(get_session),
    principal: Principal = Depends(authorize("read")),
):
    fmt = negotiate(request.headers.get("accept"), file_format, MEDIA, "the comparison (json) or its difference map (glb, csv)")
    service = ComparisonService(session, principal.tenant_id)
    if fmt == "json":
        return await run_in_threadpool(service.compare, record_a, record_b, align)
    body = await run_in_threadpool(service.difference_map, record_a, record_b, align, fmt)
    name = f"difference-{record_a[:8]}-{record_b[:8]}.{fmt}"
    return Response(body, media_type=MEDIA[fmt], headers={"Content-Disposition": f'attachment; filename="{name}"'})
