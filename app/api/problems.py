"""RFC 9457 problem details: the one place where errors become HTTP responses."""

from __future__ import annotations

import logging
from http import HTTPStatus

from fastapi import FastAPI, Request
from fastapi.exceptions import RequestValidationError
from fastapi.responses import JSONResponse
from pydantic import BaseModel, ConfigDict, Field
from starlette.exceptions import HTTPException as StarletteHTTPException
from starlette.routing import Match

from app.api.middleware import request_id_of
from app.errors import PROBLEM_TYPE_PREFIX, ServiceError, from_fit_failure
from app.geometry.errors import FitFailure
from app.services.cases import CASE_REF_FORM, CASE_REF_TITLE

PROBLEM_MEDIA_TYPE = "application/problem+json"
#: routes whose body is a document with its own problem code (by route name)
BODY_PROBLEMS = {"import_record": ("invalid_record", "Invalid calf record")}
#: pydantic's errors of a value out of its bounds (not of a value of the wrong type)
RANGE_ERRORS = {"greater_than", "greater_than_equal", "less_than", "less_than_equal", "too_long", "too_short",
                "value_error", "literal_error", "finite_number"}
#: routes whose body fields have problem codes of their own (by route name, then field)
FIELD_PROBLEMS = {"create_design": {"fabric": ("invalid_fabric", "Invalid fabric"),
                                    "targets_mmHg": ("invalid_target", "Invalid pressure target")}}
#: path parameters no problem repeats in its ``instance`` (the route's template instead)
SENSITIVE_PATH_PARAMETERS = {"case_ref"}
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
    request_id: str | None = Field(None, description="the request's X-Request-ID: quote it when asking about this error")


def _instance(request: Request) -> str:
    """The problem's ``instance``: the request's path, or its route's template where the
    path carries a case reference (a clinic's pseudonymous id, or a name sent by mistake,
    is repeated in no answer: app.services.cases)."""
    route = request.scope.get("route")
    if route is not None and SENSITIVE_PATH_PARAMETERS & set(request.scope.get("path_params") or {}):
        return str(getattr(route, "path", request.url.path))
    return str(request.url.path)


def problem_response(request: Request, status: int, code: str, title: str, detail: str, extra: dict | None = None) -> JSONResponse:
    body = {
        "type": PROBLEM_TYPE_PREFIX + code,
        "title": title,
        "status": status,
        "detail": detail,
        "instance": _instance(request),
        "code": code,
        **(extra or {}),
    }
    request_id = request_id_of(request.scope)
    if request_id:
        body["request_id"] = request_id
    response = JSONResponse(body, status_code=status, media_type=PROBLEM_MEDIA_TYPE)
    if request_id:  # a 500 is sent from outside the middleware that adds it
        response.headers["X-Request-ID"] = request_id
    return response


def install_problem_handlers(app: FastAPI) -> None:
    @app.exception_handler(ServiceError)
    async def service_error(request: Request, exc: ServiceError):
        response = problem_response(request, exc.status, exc.code, exc.title, exc.detail, exc.extra)
        response.headers.update(exc.headers)
        return response

    @app.exception_handler(FitFailure)
    async def fit_failure(request: Request, exc: FitFailure):
        error = from_fit_failure(exc)
        return problem_response(request, error.status, error.code, error.title, error.detail)

    @app.exception_handler(RequestValidationError)
    async def invalid_request(request: Request, exc: RequestValidationError):
        errors = [{"loc": list(e.get("loc", ())), "msg": _message(e), "type": e.get("type", "")} for e in exc.errors()]
        detail = "; ".join(f"{'.'.join(str(p) for p in e['loc'])}: {e['msg']}" for e in errors[:10]) or "invalid request"
        if len(errors) > 10:
            detail += f"; and {len(errors) - 10} more"
        code, title = "invalid_request", "The request is not valid"
        route = request.scope.get("route")
        document = errors and all(e["loc"][:1] == ["body"] and e["type"] != "json_invalid" for e in errors)
        if document and getattr(route, "name", None) in BODY_PROBLEMS:
            code, title = BODY_PROBLEMS[route.name]
        fields = FIELD_PROBLEMS.get(getattr(route, "name", None), {})
        named = {e["loc"][1] for e in errors if len(e["loc"]) > 1 and e["loc"][0] == "body"}
        out_of_range = all(e["type"] in RANGE_ERRORS for e in errors)
        if document and out_of_range and len(named) == 1 and next(iter(named)) in fields:
            code, title = fields[next(iter(named))]
        parameters = {str(e["loc"][-1]) for e in errors if e["loc"][:1] in (["query"], ["path"])}
        if len(parameters) == 1 and len(errors) == 1 and next(iter(parameters)) in PARAMETER_PROBLEMS:
            code, title = PARAMETER_PROBLEMS[next(iter(parameters))]
        return problem_response(request, 422, code, title, detail, {"errors": errors[:50]})

    @app.exception_handler(StarletteHTTPException)
    async def http_error(request: Request, exc: StarletteHTTPException):
        phrase = HTTPStatus(exc.status_code).phrase
        code = "payload_too_large" if exc.status_code == 413 else phrase.lower().replace(" ", "_").replace("-", "_")
        detail = exc.detail if isinstance(exc.detail, str) else phrase
        if exc.status_code == 400 and detail == "There was an error parsing the body":  # FastAPI's words
            detail = ("the request body cannot be read as JSON: it must be UTF-8 JSON, nested at most a few hundred "
                      "levels deep")
        headers = dict(exc.headers or {})
        if exc.status_code == 405:
            # every method of the path (Starlette names only the first route's)
            allowed = allowed_methods(request)
            headers["Allow"] = ", ".join(allowed)
            detail = f"{request.method} is not allowed here; use {' or '.join(allowed)}"
        response = problem_response(request, exc.status_code, code, phrase, detail)
        for key, value in headers.items():
            response.headers[key] = value
        return response

    @app.exception_handler(Exception)
    async def unexpected(request: Request, exc: Exception):  # pragma: no cover - a bug
        log.exception("unhandled error on %s %s", request.method, request.url.path)
        return problem_response(request, 500, "internal_error", "Internal server error", "an unexpected error occurred; it has been logged")


#: what a parameter that fails its pattern should look like, in words (by name)
PATTERN_HINTS = {
    "heights": "comma-separated numbers in mm, e.g. 50,120.5",
    "cursor": "the next_cursor of the previous page, as the service sent it",
    "Idempotency-Key": "1 to 255 printable ASCII characters without spaces, e.g. a UUID",
    "case_ref": CASE_REF_FORM,
    "since": "a day, YYYY-MM-DD",
    "until": "a day, YYYY-MM-DD",
    "grid": "ALONGxAROUND control points, e.g. 7x15 or 12x24",
}
#: parameters whose own problem code a value of the wrong form answers (by name): the
#: README promises invalid_case_ref for a case reference that is a name or a date
PARAMETER_PROBLEMS = {"case_ref": ("invalid_case_ref", CASE_REF_TITLE)}


def _message(error: dict) -> str:
    """Pydantic's message, except a regular expression, which says nothing to a person."""
    name = str(error.get("loc", ("",))[-1])
    if error.get("type") == "string_pattern_mismatch":
        return f"expected {PATTERN_HINTS.get(name, 'another form')}"
    return error.get("msg", "")


def allowed_methods(request: Request) -> list[str]:
    """The methods some route of the app serves at the request's path (each method is
    tried against the router: included routers hide their routes' methods)."""
    allowed = []
    for method in ("GET", "POST", "PUT", "PATCH", "DELETE"):
        scope = {**request.scope, "method": method}
        if any(route.matches(scope)[0] is Match.FULL for route in request.app.router.routes):
            allowed.append(method)
    return allowed


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
    """The Problem schema, and every 422 documented as what it is: FastAPI documents its
    request validation errors as application/json HTTPValidationError, but this service
    answers them (like every error) as application/problem+json."""
    components = schema.setdefault("components", {}).setdefault("schemas", {})
    components["Problem"] = Problem.model_json_schema(ref_template="#/components/schemas/{model}")
    problem = {PROBLEM_MEDIA_TYPE: {"schema": {"$ref": "#/components/schemas/Problem"}}}
    for operations in schema.get("paths", {}).values():
        for operation in operations.values():
            responses = operation.get("responses", {})
            if "422" in responses:
                described = responses["422"].get("description", "")
                if described in ("", "Validation Error"):
                    described = "invalid_request: a parameter or the body is not valid (the detail names it)"
                elif "invalid_request" not in described:
                    described += "; invalid_request: a parameter or the body is not valid"
                responses["422"] = {"description": described, "content": problem}
    for name in ("HTTPValidationError", "ValidationError"):
        components.pop(name, None)
    return schema


def auth_problems() -> dict:
    """The problems every /api/v1 route can answer about its API key."""
    return problems(
        s401="missing_key / invalid_key: no API key, or a malformed, unknown, revoked or expired one "
        "(WWW-Authenticate: Bearer)",
        s403="insufficient_scope: the key lacks the scope this operation needs",
        s429="rate_limited: the key sent more requests (or uploads) than its limit; Retry-After says when to retry",
    )
