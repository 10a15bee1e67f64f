"""RFC 9457 problem details: the one place where errors become HTTP responses."""

from __future__ import annotations

import logging
from http import HTTPStatus

from fastapi import FastAPI, Request
from fastapi.exceptions import RequestValidationError
from fastapi.responses import JSONResponse
from pydantic import BaseModel, ConfigDict, Field
from starlette.exceptions import HTTPException as StarletteHTTPException

from app.errors import PROBLEM_TYPE_PREFIX, ServiceError, from_fit_failure
from app.geometry.errors import FitFailure

PROBLEM_MEDIA_TYPE = "application/problem+json"
log = logging.getLogger("calf_nurbs.api")


class Problem(BaseModel):
    """An RFC 9457 problem; ``code`` repeats the last segment of ``type``."""

    model_config = ConfigDict(extra="allow")
    type: str = Field(examples=[PROBLEM_TYPE_PREFIX + "no_ankle"])
    title: str
    status: int
    detail: str
    instance: str | None = None
    code: str


def problem_response(request: Request, status: int, code: str, title: str, detail: str, extra: dict | None = None) -> JSONResponse:
    body = {
        "type": PROBLEM_TYPE_PREFIX + code,
        "title": title,
        "status": status,
        "detail": detail,
        "instance": str(request.url.path),
        "code": code,
        **(extra or {}),
    }
    return JSONResponse(body, status_code=status, media_type=PROBLEM_MEDIA_TYPE)


def install_problem_handlers(app: FastAPI) -> None:
    @app.exception_handler(ServiceError)
    async def service_error(request: Request, exc: ServiceError):
        response = problem_response(request, exc.status, exc.code, exc.title, exc.detail, exc.extra)
        if exc.status == 401:
            response.headers["WWW-Authenticate"] = 'Bearer realm="calf-nurbs"'
        return response

    @app.exception_handler(FitFailure)
    async def fit_failure(request: Request, exc: FitFailure):
        error = from_fit_failure(exc)
        return problem_response(request, error.status, error.code, error.title, error.detail)

    @app.exception_handler(RequestValidationError)
    async def invalid_request(request: Request, exc: RequestValidationError):
        errors = [{"loc": list(e.get("loc", ())), "msg": e.get("msg", ""), "type": e.get("type", "")} for e in exc.errors()]
        detail = "; ".join(f"{'.'.join(str(p) for p in e['loc'])}: {e['msg']}" for e in errors) or "invalid request"
        return problem_response(request, 422, "invalid_request", "The request is not valid", detail, {"errors": errors})

    @app.exception_handler(StarletteHTTPException)
    async def http_error(request: Request, exc: StarletteHTTPException):
        phrase = HTTPStatus(exc.status_code).phrase
        code = phrase.lower().replace(" ", "_").replace("-", "_")
        detail = exc.detail if isinstance(exc.detail, str) else phrase
        response = problem_response(request, exc.status_code, code, phrase, detail)
        for key, value in (exc.headers or {}).items():
            response.headers[key] = value
        return response

    @app.exception_handler(Exception)
    async def unexpected(request: Request, exc: Exception):  # pragma: no cover - a bug
        log.exception("unhandled error on %s %s", request.method, request.url.path)
        return problem_response(request, 500, "internal_error", "Internal server error", "an unexpected error occurred; it has been logged")


def problems(**statuses: str) -> dict:
    """OpenAPI ``responses`` entries for the problems a route can answer.

    ``problems(s404="no record with this id", ...)``: the key's digits are the status.
    """
    responses = {}
    for key, description in statuses.items():
        status = int(key.lstrip("s"))
        responses[status] = {
            "description": description,
            "content": {PROBLEM_MEDIA_TYPE: {"schema": {"$ref": "#/components/schemas/Problem"}}},
        }
    return responses


def add_problem_schema(schema: dict) -> dict:
    components = schema.setdefault("components", {}).setdefault("schemas", {})
    components["Problem"] = Problem.model_json_schema(ref_template="#/components/schemas/{model}")
    return schema


def auth_problems() -> dict:
    """The problems every /api/v1 route can answer about its API key."""
    return problems(
        s401="missing_key / invalid_key: no API key, or a malformed, unknown, revoked or expired one "
        "(WWW-Authenticate: Bearer)",
        s403="insufficient_scope: the key lacks the scope this operation needs",
    )
