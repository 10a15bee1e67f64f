"""Records: list, read, import, delete, the surface as STL/GLB/glTF, measurements."""

from __future__ import annotations

from datetime import UTC, date, datetime, time, timedelta
from typing import Literal

from fastapi import APIRouter, Body, Depends, Query, Request, Response
from fastapi.concurrency import run_in_threadpool
from sqlalchemy.orm import Session

from app.api.auth import authorize
from app.api.deps import get_session, get_store
from app.api.negotiation import negotiate
from app.api.problems import auth_problems, problems
from app.api.schemas import CalfRecordBody, MeasurementsOut, RecordOut, RecordPage, ScanPointsOut
from app.cad import CAD_EXTENSIONS, CAD_MEDIA_TYPES, TIMESTAMPED_FORMATS
from app.errors import InvalidRequest, Unprocessable
from app.services.cases import CASE_REF_PATTERN, validate_case_ref
from app.services.deviations import MAX_POINTS as MAX_SCAN_POINTS
from app.services.deviations import DeviationService
from app.services.keys import Principal
from app.services.records import ALONG_RANGE, AROUND_RANGE, MAX_SURFACE_SAMPLES, SURFACE_MEDIA_TYPES, RecordService, surface_etag
from app.services.storage import ScanStore

#: comma-separated decimal numbers (mm)
_NUMBER = r"[-+]?(\d+(\.\d*)?|\.\d+)([eE][-+]?\d+)?"
HEIGHTS_PATTERN = rf"^\s*{_NUMBER}(\s*,\s*{_NUMBER})*\s*$"

router = APIRouter(prefix="/api/v1", tags=["records"], responses=auth_problems())



def record_out(record) -> dict:
    return {**record.body, "id": record.id, "source": record.source, "created_at": record.created_at, "scan_id": record.scan_id,
            "case_ref": record.case_ref}


def record_summary(record) -> dict:
    return {
        "id": record.id,
        "source": record.source,
        "side": record.side,
        "case_ref": record.case_ref,
        "error_index": record.error_index,
        "created_at": record.created_at,
        "landmarks": record.body.get("landmarks", {}),
        "links": {
            "self": f"/api/v1/records/{record.id}",
            "surface": f"/api/v1/records/{record.id}/surface",
            "measurements": f"/api/v1/records/{record.id}/measurements",
        },
    }


DAY_PATTERN = r"^[0-9]{4}-[0-9]{2}-[0-9]{2}$"


def _day(value: str, name: str) -> date:
    try:
        return date.fromisoformat(value)
    except ValueError as exc:
        raise InvalidRequest(f"{name} must be a calendar day YYYY-MM-DD, not {value!r}") from exc


@router.get("/records", response_model=RecordPage, summary="Records, newest first (keyset pagination), by side, case and date",
            responses=problems(s400="invalid_cursor", s422="invalid_request (not a calendar day, or until before since), "
                               "invalid_case_ref"))
def list_records(
    limit: int = Query(50, ge=1, le=500),
    cursor: str | None = Query(None, pattern=r"^[A-Za-z0-9_=-]{1,200}$", description="next_cursor of the previous page"),
    side: Literal["left", "right", "unknown"] | None = Query(None, description="only records of this side"),
    since: str | None = Query(None, pattern=DAY_PATTERN, description="only records created on or after this day "
                              "(UTC), YYYY-MM-DD"),
    until: str | None = Query(None, pattern=DAY_PATTERN, description="only records created before the end of this "
                              "day (UTC), YYYY-MM-DD"),
    case_ref: str | None = Query(None, pattern=CASE_REF_PATTERN,
                                 description="only records of this case (the case reference of their upload)"),
    session: Session = Depends(get_session),
    principal: Principal = Depends(authorize("read")),
):
    start = datetime.combine(_day(since, "since"), time.min, tzinfo=UTC) if since else None
    end = datetime.combine(_day(until, "until") + timedelta(days=1), time.min, tzinfo=UTC) if until else None
    rows, next_cursor = RecordService(session, principal.tenant_id).page(limit, cursor, side, start, end,
                                                                         validate_case_ref(case_ref))
    return {"items": [record_summary(r) for r in rows], "next_cursor": next_cursor}


@router.get("/records/{record_id}", response_model=RecordOut, summary="A record: control points, knots, weights, landmarks, fit statistics",
            responses=problems(s404="record_not_found"))
def get_record(record_id: str, response: Response, session: Session = Depends(get_session),
               principal: Principal = Depends(authorize("read"))):
    record = RecordService(session, principal.tenant_id).get(record_id)
    response.headers["ETag"] = f'"{record.etag}"'
    return record_out(record)


@router.post("/records", status_code=201, response_model=RecordOut, summary="Import a record made elsewhere (validated)",
             responses={201: {"description": "Created", "headers": {"Location": {"schema": {"type": "string"}}}},
                        **problems(s400="bad_request: the body is not UTF-8 JSON",
                                   s422="invalid_record: knots, shapes, weights or numbers not valid, or not a leg's tube (a ring "
                                   "under 5 mm in radius or not winding once round its centre, height not rising "
                                   "along v, under 20 mm long); surface_too_costly: a patch cost (nu - p)(nv - q)"
                                   "(p + 1)(q + 1) over 50,000, a net over 1,200 mm tall or 300 mm from the axis; "
                                   "invalid_request", s413="payload_too_large: a body over CALF_MAX_JSON_KB")})
def import_record(response: Response, data: CalfRecordBody = Body(..., description="a calf record (schema_version 1, 2 or 3)"),
                  session: Session = Depends(get_session), principal: Principal = Depends(authorize("upload"))):
    service = RecordService(session, principal.tenant_id)
    record = service.import_record(data.model_dump(exclude_none=True))
    session.commit()
    response.headers["Location"] = f"/api/v1/records/{record.id}"
    return record_out(record)


@router.delete("/records/{record_id}", status_code=204, summary="Delete a record (its scan stays stored)",
               responses=problems(s404="record_not_found"))
def delete_record(record_id: str, session: Session = Depends(get_session), principal: Principal = Depends(authorize("upload"))):
    RecordService(session, principal.tenant_id).delete(record_id)
    session.commit()
    return Response(status_code=204)


def negotiate_surface_format(accept: str | None, query_format: str | None) -> str:
    """?format= wins; otherwise the best of Accept (RFC 9110 q-values); */* and model/* mean STL."""
    return negotiate(accept, query_format, SURFACE_MEDIA_TYPES, "this surface")


@router.get(
    "/records/{record_id}/surface",
    summary="The surface: tessellated in the scan's coordinates (STL, GLB, glTF), or exact in the calf frame, mm "
            "(STEP, IGES, 3dm, geomdl JSON)",
    response_class=Response,
    responses={
        200: {"description": "The mesh",
              "content": {m: {"schema": {"type": "string", "format": "binary"}} for m in SURFACE_MEDIA_TYPES.values()},
              "headers": {"ETag": {"schema": {"type": "string"}}, "Content-Disposition": {"schema": {"type": "string"}}}},
        304: {"description": "Not modified (If-None-Match matched the ETag)"},
        **problems(s404="record_not_found, leg_model_not_found", s406="not_acceptable: no supported media type in Accept / ?format=",
                   s422="invalid_density, invalid_record"),
    },
)
async def get_surface(
    record_id: str,
    request: Request,
    file_format: Literal["stl", "glb", "gltf", "step", "iges", "3dm", "geomdl"] | None = Query(
        None, alias="format", description="overrides Accept; step, iges, 3dm and geomdl are the exact B-spline "
        "(no tessellation) in the record's calf frame: B at the origin, z up the leg, y anterior, mm"),
    around: int = Query(144, ge=AROUND_RANGE[0], le=AROUND_RANGE[1], description="samples around the leg (meshes)"),
    along: int = Query(100, ge=ALONG_RANGE[0], le=ALONG_RANGE[1],
                       description=f"samples along the leg; around x along at most {MAX_SURFACE_SAMPLES}"),
    part: Literal["calf", "leg"] = Query("calf", description="calf: the paper's calf, B to D; leg: the leg model "
                                         "from B to G (records whose scan reaches the top of the thigh; else 404 "
                                         "saying why)"),
    session: Session = Depends(get_session),
    principal: Principal = Depends(authorize("read")),
):
    fmt = negotiate_surface_format(request.headers.get("accept"), file_format)
    service = RecordService(session, principal.tenant_id)
    record = await run_in_threadpool(service.get, record_id)
    exact = fmt in CAD_MEDIA_TYPES  # the sampling density does not apply to the exact formats
    etag = f'"{surface_etag(record.etag, fmt, 0 if exact else around, 0 if exact else along, part)}"'
    if fmt in TIMESTAMPED_FORMATS:
        # STEP, IGES and 3dm writers stamp the time into the file: the same surface, not
        # the same bytes, so the validator is weak (RFC 9110 8.8.1)
        etag = f"W/{etag}"
    # If-None-Match compares weakly: W/"x" matches "x"
    matches = [tag.strip().removeprefix("W/") for tag in (request.headers.get("if-none-match") or "").split(",")]
    if etag.removeprefix("W/") in matches or "*" in matches:
        return Response(status_code=304, headers={"ETag": etag})
    data = await run_in_threadpool(service.surface, record, fmt, around, along, part)
    side = record.side or "leg"
    filename = f"{part}-{record.id[:12]}-{side}.{CAD_EXTENSIONS.get(fmt, fmt)}"
    return Response(
        content=data,
        media_type=SURFACE_MEDIA_TYPES[fmt],
        headers={"ETag": etag, "Content-Disposition": f'attachment; filename="{filename}"', "Vary": "Accept"},
    )


@router.get("/records/{record_id}/measurements", response_model=MeasurementsOut,
            summary="Girths at B, B1, C, D and at any heights, measured on the surface itself; lengths between landmarks",
            responses=problems(s404="record_not_found", s422="height_out_of_range, invalid_request"))
async def get_measurements(
    record_id: str,
    heights: str | None = Query(None, pattern=HEIGHTS_PATTERN, max_length=2000,
                                description="comma-separated calf-frame heights in mm, e.g. 50,120.5"),
    session: Session = Depends(get_session),
    principal: Principal = Depends(authorize("read")),
):
    extra: list[float] = []
    if heights:
        try:
            extra = [float(h) for h in heights.split(",") if h.strip()]
        except ValueError as exc:
            raise Unprocessable(f"heights must be numbers in mm separated by commas, not {heights!r}", code="invalid_heights") from exc
        if len(extra) > 200:
            raise Unprocessable("at most 200 heights per request", code="invalid_heights")
    return await run_in_threadpool(RecordService(session, principal.tenant_id).measurements, record_id, extra)


@router.get("/records/{record_id}/scan-points", response_model=ScanPointsOut,
            summary="The scan's points of the calf (calf frame, mm) and their distance to the surface",
            responses=problems(s404="record_not_found, scan_not_found (an imported or population record)",
                               s422="scan_unreadable"))
async def get_scan_points(
    record_id: str,
    limit: int = Query(20000, ge=100, le=MAX_SCAN_POINTS, description="at most this many points (a fixed stride)"),
    session: Session = Depends(get_session),
    store: ScanStore = Depends(get_store),
    principal: Principal = Depends(authorize("read")),
):
    return await run_in_threadpool(DeviationService(session, principal.tenant_id, store).scan_points, record_id, limit)
