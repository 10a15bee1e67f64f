"""Ready-to-wear size charts: register (JSON or CSV), list, read; a record's size decision."""

from __future__ import annotations

import csv
import json

from fastapi import APIRouter, Depends, Query, Request, Response
from sqlalchemy.orm import Session

from app.api.auth import authorize
from app.api.deps import get_session
from app.api.problems import auth_problems, problems
from app.api.schemas import SizeChartOut, SizeDecisionOut
from app.errors import BadRequest, PayloadTooLarge, UnsupportedMediaType, from_fit_failure
from app.geometry.errors import FitFailure
from app.geometry.garment.size_charts import CHART_POINTS, MAX_SIZES, STOCKING_TYPES, size_chart_dict_from_csv
from app.services.keys import Principal
from app.services.size_charts import MAX_CHART_BYTES, SizeChartService, chart_view

router = APIRouter(prefix="/api/v1", tags=["size charts"], responses=auth_problems())

#: the chart's JSON form (app.geometry.garment.size_charts); cross-field rules (min < max,
#: unique size names) are checked by the service and answered 422 with the fault named
_RANGE = {"type": "array", "items": {"type": "number", "exclusiveMinimum": 0, "maximum": 2500}, "minItems": 2, "maxItems": 2,
          "description": "[min, max] in mm"}
CHART_SCHEMA = {
    "type": "object",
    "required": ["product", "type", "sizes"],
    "properties": {
        "product": {"type": "string", "minLength": 1, "maxLength": 100},
        "type": {"type": "string", "enum": list(STOCKING_TYPES), "description": "AD knee-high, AG thigh-high"},
        "source": {"type": "string", "maxLength": 500},
        "sizes": {"type": "array", "minItems": 1, "maxItems": MAX_SIZES, "items": {
            "type": "object", "required": ["name", "ranges"],
            "properties": {"name": {"type": "string", "minLength": 1, "maxLength": 40},
                           "ranges": {"type": "object", "minProperties": 1, "additionalProperties": False,
                                      "properties": {point: _RANGE for point in CHART_POINTS}}}}},
    },
}
CHART_BODY = {"requestBody": {"required": True, "description": "the chart as JSON, or as CSV ('# product: ...', "
              "'# type: AD' lines, then the columns size, point, min_mm, max_mm)",
              "content": {"application/json": {"schema": CHART_SCHEMA}, "text/csv": {"schema": {"type": "string"}}}}}


@router.post("/size-charts", status_code=201, response_model=SizeChartOut, openapi_extra=CHART_BODY,
             summary="Register a ready-to-wear size chart (JSON or CSV)",
             responses=problems(s400="bad_request: not UTF-8 JSON / CSV", s413="payload_too_large: over 64 kB",
                                s415="unsupported_media_type",
                                s422="invalid_size_chart: the chart's fault, named"))
async def register_chart(request: Request, response: Response, session: Session = Depends(get_session),
                         principal: Principal = Depends(authorize("design"))):
    media = (request.headers.get("content-type") or "").split(";")[0].strip().lower()
    raw = await request.body()
    if len(raw) > MAX_CHART_BYTES:
        raise PayloadTooLarge(f"a size chart is at most {MAX_CHART_BYTES // 1024} kB")
    try:
        text = raw.decode("utf-8")
        data = json.loads(text) if media == "application/json" else size_chart_dict_from_csv(text) if media == "text/csv" else None
    except (UnicodeDecodeError, json.JSONDecodeError, csv.Error) as exc:
        raise BadRequest("the chart is not UTF-8 JSON or CSV") from exc
    except FitFailure as failure:
        raise from_fit_failure(failure) from failure
    if data is None:
        raise UnsupportedMediaType("send the chart as application/json or text/csv")
    row, chart = SizeChartService(session, principal.tenant_id).register(data)
    response.headers["Location"] = f"/api/v1/size-charts/{row.id}"
    return chart_view(row.id, chart, example=False)


@router.get("/size-charts", response_model=list[SizeChartOut],
            summary="Your clinic's size charts, after the shipped examples (ANSUR II-derived knee-high and thigh-high, "
                    "labelled as examples)")
def list_charts(session: Session = Depends(get_session), principal: Principal = Depends(authorize("read"))):
    return SizeChartService(session, principal.tenant_id).listing()


@router.get("/size-charts/{chart_id}", response_model=SizeChartOut, summary="A size chart",
            responses=problems(s404="size_chart_not_found"))
def get_chart(chart_id: str, session: Session = Depends(get_session), principal: Principal = Depends(authorize("read"))):
    chart, example = SizeChartService(session, principal.tenant_id).get(chart_id)
    return chart_view(chart_id, chart, example)


@router.get("/records/{record_id}/size-decision", response_model=SizeDecisionOut,
            summary="Which sizes of a chart fit the leg at every point, the best one, or made to measure with each "
                    "point outside its range and by how much",
            responses=problems(s404="record_not_found, size_chart_not_found"))
def decide_size(record_id: str,
                chart: str = Query(..., description="a size chart id (example-ansur2-ad, example-ansur2-ag: the knee-high "
                                   "and thigh-high examples)"),
                session: Session = Depends(get_session), principal: Principal = Depends(authorize("read"))):
    return SizeChartService(session, principal.tenant_id).decide(record_id, chart)
