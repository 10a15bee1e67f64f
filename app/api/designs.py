"""Stocking designs: create from a record, read, knitting spec, pressure map, charts."""

from __future__ import annotations

from typing import Literal

from fastapi import APIRouter, Depends, Query, Request, Response
from fastapi.concurrency import run_in_threadpool
from fastapi.encoders import jsonable_encoder
from fastapi.responses import JSONResponse
from sqlalchemy.orm import Session

from app.api.auth import authorize
from app.api.deps import get_session
from app.api.idempotency import IDEMPOTENCY_PROBLEMS, REPLAYED, Stage, answer_once, idempotency_key
from app.api.negotiation import negotiate
from app.api.problems import auth_problems, problems
from app.api.schemas import DesignOut, DesignRequest, OrderOut
from app.errors import NotFound
from app.services import charts
from app.services.designs import DesignService, color_scale, design_view, knitting_csv, pressure_grid, pressure_map_csv, pressure_map_glb
from app.services.keys import Principal
from app.services.order_pdf import order_pdf
from app.services.orders import OrderService

PRESSURE_MAP_MEDIA = {"glb": "model/gltf-binary", "csv": "text/csv"}
ORDER_MEDIA = {"json": "application/json", "pdf": "application/pdf"}

router = APIRouter(prefix="/api/v1", tags=["designs"], responses=auth_problems())

DESIGN_PROBLEMS = problems(
    s400="bad_request: the body is not UTF-8 JSON",
    s404="record_not_found",
    s422="invalid_target, invalid_fabric, unreachable_pressure (the fabric would have to stretch beyond its table or "
    "strain limit), invalid_record, invalid_request",
)


@router.post("/records/{record_id}/designs", status_code=201, response_model=DesignOut,
             summary="Design a graduated compression stocking from a record (stored with its inputs)",
             responses={201: {"description": "Created", "headers": {"Location": {"schema": {"type": "string"}}, **REPLAYED}},
                        **DESIGN_PROBLEMS, **IDEMPOTENCY_PROBLEMS})
async def create_design(record_id: str, body: DesignRequest, request: Request, session: Session = Depends(get_session),
                        principal: Principal = Depends(authorize("design")), idempotency: str | None = Depends(idempotency_key)):
    inputs = body.model_dump()

    async def design(stage: Stage | None) -> JSONResponse:
        answer: dict = {}

        def keep_answer(made) -> None:  # in the design's transaction
            answer["body"] = jsonable_encoder(design_view(made))
            if stage is not None:
                stage(201, answer["body"], f"/api/v1/designs/{made.id}")

        made = await run_in_threadpool(DesignService(session, principal.tenant_id).create, record_id, inputs, keep_answer)
        return JSONResponse(answer["body"], status_code=201, headers={"Location": f"/api/v1/designs/{made.id}"})

    return await answer_once(request, session, principal, idempotency, "create_design",
                             {"record_id": record_id, "inputs": body.model_dump(mode="json")}, design)


@router.get("/records/{record_id}/designs", response_model=list[DesignOut], summary="The designs made from a record",
            responses=problems(s404="record_not_found"))
def list_designs(record_id: str, session: Session = Depends(get_session), principal: Principal = Depends(authorize("read", "design"))):
    return [design_view(d) for d in DesignService(session, principal.tenant_id).for_record(record_id)]


@router.get("/designs/{design_id}", response_model=DesignOut, summary="A design: pressures, checks, hot spots, knitting spec",
            responses=problems(s404="design_not_found"))
def get_design(design_id: str, session: Session = Depends(get_session), principal: Principal = Depends(authorize("read", "design"))):
    return design_view(DesignService(session, principal.tenant_id).get(design_id))


@router.get("/designs/{design_id}/knitting-spec", summary="The knitting specification as CSV (one row per height)",
            response_class=Response,
            responses={200: {"content": {"text/csv": {}}, "description": "CSV"}, **problems(s404="design_not_found")})
def get_knitting_spec(design_id: str, session: Session = Depends(get_session), principal: Principal = Depends(authorize("read", "design"))):
    design = DesignService(session, principal.tenant_id).get(design_id)
    return Response(knitting_csv(design), media_type="text/csv",
                    headers={"Content-Disposition": f'attachment; filename="knitting-{design.id[:12]}.csv"'})


@router.get("/designs/{design_id}/pressure-map",
            summary="Local skin pressure over the surface: GLB with vertex colours and a legend, or CSV",
            response_class=Response,
            responses={200: {"content": {"model/gltf-binary": {}, "text/csv": {}}, "description": "the map"},
                       **problems(s404="design_not_found", s406="not_acceptable")})
async def get_pressure_map(design_id: str, request: Request,
                           file_format: Literal["glb", "csv"] | None = Query(None, alias="format", description="overrides Accept"),
                           session: Session = Depends(get_session), principal: Principal = Depends(authorize("read", "design"))):
    fmt = negotiate(request.headers.get("accept"), file_format, PRESSURE_MAP_MEDIA, "the pressure map")
    service = DesignService(session, principal.tenant_id)
    design = await run_in_threadpool(service.get, design_id)
    record = await run_in_threadpool(service.record_of, design)
    if fmt == "csv":
        body = await run_in_threadpool(pressure_map_csv, design, record)
        return Response(body, media_type="text/csv",
                        headers={"Content-Disposition": f'attachment; filename="pressure-{design.id[:12]}.csv"'})
    body = await run_in_threadpool(pressure_map_glb, design, record)
    return Response(body, media_type="model/gltf-binary",
                    headers={"Content-Disposition": f'attachment; filename="pressure-{design.id[:12]}.glb"'})


@router.get("/designs/{design_id}/charts/{name}.png", summary="PNG charts: profile, pressure or map", response_class=Response,
            responses={200: {"content": {"image/png": {}}, "description": "PNG"}, **problems(s404="design_not_found or chart_not_found")})
async def get_chart(design_id: str, name: str, session: Session = Depends(get_session),
                    principal: Principal = Depends(authorize("read", "design"))):
    if name not in charts.CHARTS:
        raise NotFound(f"no chart {name!r}; charts are {', '.join(charts.CHARTS)}", code="chart_not_found")
    service = DesignService(session, principal.tenant_id)
    design = await run_in_threadpool(service.get, design_id)
    record = await run_in_threadpool(service.record_of, design)

    def draw() -> bytes:
        if name == "profile":
            return charts.profile_chart(record, design.result)
        if name == "pressure":
            return charts.pressure_chart(design.result)
        rings, local = pressure_grid(design, record)
        top, _ = color_scale(design, local)
        return charts.map_chart(design.result, rings, local, top)

    return Response(await run_in_threadpool(draw), media_type="image/png")


@router.get("/designs/{design_id}/order", response_model=OrderOut,
            summary="The order of a design: JSON, or PDF with a leg diagram (Accept or ?format=)",
            responses={200: {"content": {"application/pdf": {}}, "description": "the order"},
                       **problems(s404="design_not_found, size_chart_not_found", s406="not_acceptable")})
async def get_order(design_id: str, request: Request,
                    chart: str | None = Query(None, max_length=64,
                                              description="size chart for the ready-to-wear decision (default: the shipped example)"),
                    file_format: Literal["json", "pdf"] | None = Query(None, alias="format", description="overrides Accept"),
                    session: Session = Depends(get_session), principal: Principal = Depends(authorize("read", "design"))):
    fmt = negotiate(request.headers.get("accept"), file_format, ORDER_MEDIA, "the order")
    order = await run_in_threadpool(OrderService(session, principal.tenant_id).order, design_id, chart)
    if fmt == "json":
        return order
    body = await run_in_threadpool(order_pdf, order)
    return Response(body, media_type="application/pdf",
                    headers={"Content-Disposition": f'attachment; filename="order-{design_id[:12]}.pdf"'})
