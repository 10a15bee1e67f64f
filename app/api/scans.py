"""POST /api/v1/scans: upload a scan, get a fitting job."""

from __future__ import annotations

from dataclasses import asdict
from typing import Literal

from fastapi import APIRouter, Depends, Query, Request
from fastapi.concurrency import run_in_threadpool
from fastapi.responses import JSONResponse
from sqlalchemy.orm import Session

from app.api.auth import authorize
from app.api.deps import get_app_settings, get_runner, get_session, get_store
from app.api.idempotency import IDEMPOTENCY_PROBLEMS, REPLAYED, Stage, answer_once, idempotency_key
from app.api.problems import auth_problems, problems
from app.api.schemas import ErasureOut, JobOut
from app.geometry.scan import SUPPORTED_FORMATS
from app.jobs.runner import EmbeddedRunner
from app.services.cases import CASE_REF_PATTERN, validate_case_ref
from app.services.erasure import ErasureService
from app.services.fitting import parse_options
from app.services.jobs import JobService
from app.services.keys import Principal
from app.services.storage import ScanStore
from app.services.upload_flow import UploadFlow
from app.services.uploads import MEDIA_TYPES, receive_upload
from app.settings import Settings

ScanFormat = Literal[SUPPORTED_FORMATS]  # type: ignore[valid-type]
#: an lsq control net, ALONGxAROUND (the bounds are checked with the reason in words)
GRID_PATTERN = r"^[0-9]{1,2}[xX][0-9]{1,2}$"

router = APIRouter(prefix="/api/v1", tags=["scans"], responses=auth_problems())

_SCAN_BODY = {"schema": {"type": "string", "format": "binary", "minLength": 1}}
UPLOAD_BODY = {
    "requestBody": {
        "required": True,
        "description": "The scan: a multipart form (field `file`, optional fields `side`, `units`, `points`, `mode`, `grid`) "
        "or the raw file with its media type (options as query parameters; application/octet-stream needs ?format=).",
        "content": {
            "multipart/form-data": {
                "schema": {
                    "type": "object",
                    "required": ["file"],
                    "properties": {
                        "file": {"type": "string", "format": "binary", "minLength": 1},
                        "side": {"type": "string", "enum": ["left", "right"]},
                        "units": {"type": "string", "enum": ["mm", "cm", "m", "in"]},
                        "points": {"type": "integer", "minimum": 4, "maximum": 36, "default": 15},
                        "mode": {"type": "string", "enum": ["paper", "lsq"], "default": "paper"},
                        "grid": {"type": "string", "pattern": GRID_PATTERN},
                        "case_ref": {"type": "string", "pattern": CASE_REF_PATTERN},
                    },
                }
            },
            **{media: _SCAN_BODY for media in sorted(MEDIA_TYPES)},
            "application/octet-stream": _SCAN_BODY,
        },
    }
}


@router.post(
    "/scans",
    status_code=202,
    response_model=JobOut,
    summary="Upload a scan; a fitting job is queued",
    openapi_extra=UPLOAD_BODY,
    responses={
        202: {"description": "Accepted: the scan is stored and a job queued; Location points at the job",
              "headers": {"Location": {"schema": {"type": "string"}, "description": "/api/v1/jobs/{id}"}, **REPLAYED}},
        **IDEMPOTENCY_PROBLEMS,
        **problems(
            s400="empty_body, bad_request (malformed multipart, no 'file' field), truncated_body (a multipart body "
            "without its closing boundary), invalid_content_length",
            s413="payload_too_large: more bytes than CALF_MAX_UPLOAD_MB (the declared Content-Length is checked before "
            "the body is read)",
            s415="unsupported_media_type / unsupported_format",
            s422="the scan cannot be fitted, with the reason: unreadable_file, truncated_file, empty_scan, "
            "non_finite_coordinates, too_few_points, scan_too_large (more points or triangles than "
            "CALF_MAX_SCAN_POINTS / CALF_MAX_SCAN_FACES), implausible_size, not_a_leg, partial_view (the scan sees the leg from one side: "
            "the detail gives the arc without skin), knee_bent (a knee bent so far, a leg scanned seated, that the "
            "planes across the calf cut the thigh too: scan it standing or lying with the knee straight; reported by "
            "the fit job), no_calf (no calf bulge), "
            "no_ankle / no_knee (the ankle or the knee waist is not in the scan: the detail says how far the "
            "scan reaches and what a re-scan must include), several_legs (the detail lists the legs found; "
            "pass side), side_not_found, invalid_option, invalid_case_ref",
            s503="check_timeout (the upload check took too long) or runner_unavailable (its worker stopped twice)",
        ),
    },
)
async def upload_scan(
    request: Request,
    side: Literal["left", "right"] | None = Query(None, description="which leg of a whole-body scan"),
    units: Literal["mm", "cm", "m", "in"] | None = Query(
        None, description="the file's unit; detected from the extent (mm, m or cm) when omitted"),
    points: int | None = Query(None, ge=4, le=36, description="feature points per layer (paper: 8 or 15)"),
    mode: Literal["paper", "lsq"] | None = Query(
        None, description="paper: the paper's 7 x points interpolation; lsq: least squares on all the calf's points"),
    grid: str | None = Query(None, pattern=GRID_PATTERN,
                             description="lsq control net ALONGxAROUND, e.g. 7x15 (default) or 12x24"),
    file_format: ScanFormat | None = Query(None, alias="format", description="scan format for application/octet-stream"),
    case_ref: str | None = Query(None, pattern=CASE_REF_PATTERN,
                                 description="the clinic's own pseudonymous case id (1-64 letters, digits, '.', "
                                 "'_', '-'; never a name or a birth date): kept on the job and its record"),
    settings: Settings = Depends(get_app_settings),
    store: ScanStore = Depends(get_store),
    runner: EmbeddedRunner = Depends(get_runner),
    session: Session = Depends(get_session),
    principal: Principal = Depends(authorize("upload", upload=True)),
    idempotency: str | None = Depends(idempotency_key),
):
    # fair share, before the scan is received: the clinic's queue has room
    await run_in_threadpool(JobService(session, principal.tenant_id).ensure_capacity, settings.tenant_max_jobs)
    upload = await receive_upload(request.headers, request.stream(), store, settings.max_upload_bytes, file_format)
    try:
        fields = upload.fields
        options = parse_options(side or fields.get("side"), units or fields.get("units"),
                                points if points is not None else fields.get("points"),
                                mode or fields.get("mode"), grid or fields.get("grid"))
        case = validate_case_ref(case_ref or fields.get("case_ref"))
    except BaseException:
        upload.discard()
        raise

    flow = UploadFlow(session, principal.tenant_id, store, runner, request.app.state.check_gate,
                      request.app.state.metrics.check_seconds, settings.validation_timeout_s,
                      settings.max_scan_points, settings.max_scan_faces)

    async def check_and_queue(stage: Stage | None) -> JSONResponse:
        queued = await flow.check_and_queue(upload, options, stage, case)
        return JSONResponse(queued.body, status_code=202, headers={"Location": queued.location})

    content = {"sha256": upload.sha256, "format": upload.file_format, "options": options, "case_ref": case}
    try:
        return await answer_once(request, session, principal, idempotency, "upload_scan", content, check_and_queue,
                                 on_replay=upload.discard)
    except BaseException:  # a 409 for the key, a failed check or store: the received file goes
        upload.discard()
        raise


@router.delete(
    "/scans/{scan_id}",
    response_model=ErasureOut,
    summary="Erase a scan: its stored file, jobs, records, their designs and idempotent answers, in one transaction",
    responses=problems(s404="scan_not_found", s409="job_running: a fit of this scan is running; erase it after"),
)
def erase_scan(scan_id: str, session: Session = Depends(get_session), store: ScanStore = Depends(get_store),
               principal: Principal = Depends(authorize("upload"))):
    return asdict(ErasureService(session, principal.tenant_id, store).erase_scan(scan_id))
