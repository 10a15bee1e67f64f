"""Who is asking: the API key of a request (``Authorization: Bearer <key>`` or
``X-API-Key: <key>``), its tenant and its scopes.

``Depends(authorize("read"))`` on a route gives its :class:`Principal`, or answers 401
(no key, or a malformed, unknown, revoked or expired one), 403 (the key lacks every
scope the route accepts) or 429 (the key's rate limit, :mod:`app.services.rate_limits`;
``upload=True`` also takes from the key's upload bucket).  With auth off (a service bound to localhost, or
CALF_AUTH=off) a request without a key acts for the tenant "default" with every scope;
one with a key is still checked (a wrong key is refused, a valid one acts as itself).
"""

from __future__ import annotations

from fastapi import Depends, Request, Security
from fastapi.security import APIKeyHeader, HTTPAuthorizationCredentials, HTTPBearer
from sqlalchemy.orm import Session

from app.api.deps import get_session
from app.api.guard import PRINCIPAL_STATE, presented_key
from app.errors import Forbidden, TooManyRequests, Unauthorized
from app.services.keys import LOCAL_PRINCIPAL, KeyService, Principal

bearer_scheme = HTTPBearer(auto_error=False, scheme_name="bearer", description="the clinic's API key: cnk_...")
header_scheme = APIKeyHeader(name="X-API-Key", auto_error=False, scheme_name="apiKey", description="the clinic's API key: cnk_...")


def authorize(*scopes: str, upload: bool = False):
    """A dependency that admits a key holding any of ``scopes`` (admin holds all),
    within its rate limits."""

    def dependency(
        request: Request,
        credentials: HTTPAuthorizationCredentials | None = Security(bearer_scheme),
        header_key: str | None = Security(header_scheme),
        session: Session = Depends(get_session),  # the request's own session (one per request)
    ) -> Principal:
        presented = credentials.credentials if credentials is not None else header_key
        if PRINCIPAL_STATE in request.scope.get("state", {}):  # authenticated before the body was read
            principal = request.scope["state"][PRINCIPAL_STATE]
        elif not request.app.state.settings.auth_required and not presented:
            principal = LOCAL_PRINCIPAL
        else:
            # auth off, a key is still checked: a wrong key is an error the sender must
            # hear of (it would be refused once the service is exposed), not "default"
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
        # who the limit counts: the key, or (auth off) the client's address
        who = principal.key_prefix or f"address:{request.client.host if request.client else '-'}"
        request.state.tenant_id = principal.tenant_id  # for the request's log line
        limits = request.app.state.rate_limits
        for name in ("requests", "uploads") if upload else ("requests",):
            limiter = limits[name]
            wait = limiter.take(who)
            if wait:
                request.app.state.metrics.rate_limited.inc()
                raise TooManyRequests(
                    f"this API key has sent more {name} than its limit of {limiter.rate * 60:g} a minute; "
                    f"try again in {wait} s",
                    retry_after_s=wait,
                )
        return principal

    return dependency


def optional_principal(request: Request, session: Session) -> Principal | None:
    """The principal of the request's key when it has a valid one (no error otherwise):
    for public routes that show more to an operator.  Auth off: the local principal."""
    key = presented_key(dict(request.scope.get("headers") or []))
    if key is None:
        return None if request.app.state.settings.auth_required else LOCAL_PRINCIPAL
    try:
        return KeyService(session).authenticate(key)
    except Unauthorized:
        return None
