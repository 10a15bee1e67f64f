"""The service's one error hierarchy.  Each error maps to an RFC 9457 problem (see
app.api.problems), with a stable ``code`` that ends the problem ``type`` URI."""

from __future__ import annotations

from app.geometry.errors import FailureReason, FitFailure

PROBLEM_TYPE_PREFIX = "urn:calf-nurbs:problem:"


class ServiceError(Exception):
    status: int = 400
    code: str = "bad_request"
    title: str = "Bad request"
    #: response headers every error of the class carries
    headers: dict = {}

    def __init__(self, detail: str, *, code: str | None = None, title: str | None = None, extra: dict | None = None):
        super().__init__(detail)
        self.detail = detail
        if code:
            self.code = code
        if title:
            self.title = title
        self.extra = extra or {}


class BadRequest(ServiceError):
    status, code, title = 400, "bad_request", "Bad request"


class EmptyBody(ServiceError):
    status, code, title = 400, "empty_body", "The request body is empty"


class Unauthorized(ServiceError):
    """401: no valid API key (the response carries WWW-Authenticate)."""

    status, code, title = 401, "unauthorized", "An API key is needed"
    headers = {"WWW-Authenticate": 'Bearer realm="calf-nurbs"'}


class Forbidden(ServiceError):
    status, code, title = 403, "forbidden", "The API key may not do this"


class NotFound(ServiceError):
    status, code, title = 404, "not_found", "Not found"


class NotAcceptable(ServiceError):
    status, code, title = 406, "not_acceptable", "No acceptable representation"


class PayloadTooLarge(ServiceError):
    status, code, title = 413, "payload_too_large", "The upload is larger than the limit"


class UnsupportedMediaType(ServiceError):
    status, code, title = 415, "unsupported_media_type", "Unsupported scan format"


class Unprocessable(ServiceError):
    status, code, title = 422, "unprocessable", "The input cannot be processed"


class InvalidRequest(Unprocessable):
    """A parameter the service checks beyond its schema (the code and title FastAPI's own
    validation answers with: app.api.problems)."""

    code, title = "invalid_request", "The request is not valid"


class Conflict(ServiceError):
    status, code, title = 409, "conflict", "The request conflicts with an earlier one"


class TooManyRequests(ServiceError):
    """429: the key's rate limit; the response carries Retry-After (whole seconds)."""

    status, code, title = 429, "rate_limited", "Too many requests"

    def __init__(self, detail: str, retry_after_s: int, **kwargs):
        super().__init__(detail, **kwargs)
        self.headers = {"Retry-After": str(int(retry_after_s))}
        self.extra = {**self.extra, "retry_after_s": int(retry_after_s)}


class Unavailable(ServiceError):
    status, code, title = 503, "unavailable", "The service is not ready"


#: titles of the geometry core's failure reasons
FAILURE_TITLES = {
    FailureReason.UNREADABLE_FILE: "The scan file cannot be read",
    FailureReason.TRUNCATED_FILE: "The scan file is truncated",
    FailureReason.UNSUPPORTED_FORMAT: "Unsupported scan format",
    FailureReason.EMPTY_SCAN: "The scan is empty",
    FailureReason.NON_FINITE_COORDINATES: "The scan has NaN or infinite coordinates",
    FailureReason.TOO_FEW_POINTS: "The scan has too few points",
    FailureReason.TOO_SPARSE: "The point cloud is too sparse to measure",
    FailureReason.SCAN_TOO_LARGE: "The scan has more points or triangles than the service accepts",
    FailureReason.IMPLAUSIBLE_SIZE: "The scan is not the size of a leg or a body",
    FailureReason.NOT_A_LEG: "The scan is not a leg",
    FailureReason.PARTIAL_VIEW: "The scan does not go all round the leg",
    FailureReason.NO_ANKLE: "No ankle in the scanned range",
    FailureReason.NO_KNEE: "No knee in the scanned range",
    FailureReason.NO_CALF: "No calf in the scan",
    FailureReason.KNEE_BENT: "The knee is bent too far to measure the calf",
    FailureReason.SEVERAL_LEGS: "The scan holds more than one leg",
    FailureReason.SIDE_NOT_FOUND: "The leg cannot be picked out of the body",
    FailureReason.INVALID_OPTION: "Invalid fitting option",
    FailureReason.DEGENERATE_SURFACE: "The surface cannot be built",
    FailureReason.INVALID_RECORD: "Invalid calf record",
    FailureReason.SURFACE_TOO_COSTLY: "The surface is larger than the service evaluates",
    FailureReason.INVALID_TARGET: "Invalid pressure target",
    FailureReason.INVALID_FABRIC: "Invalid fabric",
    FailureReason.UNREACHABLE_PRESSURE: "The fabric cannot reach the pressure without tearing",
    FailureReason.INVALID_SIZE_CHART: "Invalid size chart",
}


def from_fit_failure(failure: FitFailure) -> ServiceError:
    """The HTTP-level error for a failure of the geometry core (415 for formats, else 422)."""
    cls = UnsupportedMediaType if failure.reason == FailureReason.UNSUPPORTED_FORMAT else Unprocessable
    return cls(failure.detail, code=failure.reason.value, title=FAILURE_TITLES.get(failure.reason))
