"""Who is asking: the API key of a request (``Authorization: Bearer <key>`` or
``X-API-Key: <key>``), its tenant and its scopes.

``Depends(authorize("read"))`` on a route gives its :class:`Principal`, or answers 401
(no key, or a malformed, unknown, revoked or expired one) or 403 (the key lacks every
scope the route accepts).  With auth off (a service bound to localhost, or
CALF_AUTH=off) every request acts for the tenant "default" with every scope.
"""

from __future__ import annotations

from fastapi import Depends, Request, Security
from fastapi.security import APIKeyHeader, HTTPAuthorizationCredentials, HTTPBearer
from sqlalchemy.orm import Session

from app.api.deps import get_session

from app.errors import Forbidden, Unauthorized
from app.services.keys import LOCAL_PRINCIPAL, KeyService, Principal

bearer_scheme = HTTPBearer(auto_error=False, scheme_name="bearer", description="the clinic's API key: cnk_...")
header_scheme = APIKeyHeader(name="X-API-Key", auto_error=False, scheme_name="apiKey", description="the clinic's API key: cnk_...")


def authorize(*scopes: str):
    """A dependency that admits a key holding any of ``scopes`` (admin holds all)."""

    def dependency(
        request: Request,
        credentials: HTTPAuthorizationCredentials | None = Security(bearer_scheme),
        header_key: str | None = Security(header_scheme),
        session: Session = Depends(get_session),  # the request's own session (one per request)
    ) -> Principal:
        if not request.app.state.settings.auth_required:
            principal = LOCAL_PRINCIPAL
        else:
            presented = credentials.credentials if credentials is not None else header_key
            if not presented:
                raise Unauthorized(
                    "this service needs your clinic's API key: send it as 'Authorization: Bearer <key>' "
                    "or 'X-API-Key: <key>'",
                    code="missing_key",
                )
            principal = KeyService(session).authenticate(presented)
        if not any(principal.allows(scope) for scope in scopes):
            raise Forbidden(
                f"this API key may not do this: it needs the scope {' or '.join(scopes)}, and has "
                f"{', '.join(sorted(principal.scopes)) or 'none'}",
                code="insufficient_scope",
            )
        return principal

    return dependency
