"""API keys: issued to a tenant (a clinic), stored as SHA-256 only, scoped, revocable,
expiring.

A key reads ``cnk_<8 hex>_<43 url-safe chars>``: the first part (``cnk_<8 hex>``) is
its public *prefix*, unique, shown in lists and safe to log; the rest is 256 random bits.
Only the SHA-256 of the whole key is stored: a fast hash is enough for a random
256-bit secret (nothing to brute-force), and it lets a key be checked with one indexed
lookup and a constant-time comparison.
"""

from __future__ import annotations

import hashlib
import hmac
import re
import secrets
from dataclasses import dataclass
from datetime import UTC, datetime, timedelta

from sqlalchemy.orm import Session

from app.db.models import DEFAULT_TENANT_ID, ApiKey
from app.db.repositories import ApiKeyRepository, TenantRepository
from app.errors import BadRequest, NotFound, Unauthorized

#: what a key may do: upload scans (and import / delete records), read records, jobs
#: and designs, make designs; admin may do everything a clinic may.  ``operator`` is the
#: service operator's, not a clinic's: the whole service's metrics and readiness details
#: (every clinic's job counts); a clinic's admin key does not hold it
SCOPES = ("upload", "read", "design", "admin", "operator")
CLINIC_SCOPES = ("upload", "read", "design")
KEY_PATTERN = re.compile(r"^(cnk_[0-9a-f]{8})_([A-Za-z0-9_-]{43})$")
#: last_used_at is written at most this often per key (a write per request would make
#: every read a database write)
TOUCH_EVERY = timedelta(minutes=1)


@dataclass(frozen=True)
class Principal:
    """Who a request acts for: the tenant, the key's prefix (None when auth is off) and
    the key's scopes."""

    tenant_id: str
    key_prefix: str | None
    scopes: frozenset

    def allows(self, scope: str) -> bool:
        return scope in self.scopes or ("admin" in self.scopes and scope in CLINIC_SCOPES + ("admin",))


#: the principal of a service running with CALF_AUTH=off (local use only)
LOCAL_PRINCIPAL = Principal(DEFAULT_TENANT_ID, None, frozenset(SCOPES))


def _digest(key: str) -> str:
    return hashlib.sha256(key.encode("ascii")).hexdigest()


def parse_scopes(text: str) -> tuple[str, ...]:
    """Scopes from ``"upload,read"`` (commas or spaces); unknown names are refused."""
    names = tuple(dict.fromkeys(n for n in re.split(r"[\s,]+", text.strip()) if n))
    unknown = [n for n in names if n not in SCOPES]
    if unknown or not names:
        raise BadRequest(f"scopes must be some of {', '.join(SCOPES)}; got {text!r}", code="invalid_scopes")
    return names


@dataclass(frozen=True)
class IssuedKey:
    key: str  # shown once, never stored
    prefix: str
    tenant: str
    scopes: tuple[str, ...]
    expires_at: datetime | None


class KeyService:
    def __init__(self, session: Session):
        self.session = session
        self.keys = ApiKeyRepository(session)
        self.tenants = TenantRepository(session)

    def create(self, tenant_name: str, scopes: tuple[str, ...], label: str | None = None,
               expires_in_days: float | None = None) -> IssuedKey:
        """A new key for ``tenant_name`` (the tenant is created if new); commits."""
        tenant_name = tenant_name.strip()
        if not tenant_name or len(tenant_name) > 100:
            raise BadRequest("the tenant name must be 1-100 characters", code="invalid_tenant")
        tenant = self.tenants.by_name(tenant_name) or self.tenants.add(tenant_name)
        expires = datetime.now(UTC) + timedelta(days=expires_in_days) if expires_in_days else None
        while True:
            prefix = f"cnk_{secrets.token_hex(4)}"
            if self.keys.by_prefix(prefix) is None:
                break
        key = f"{prefix}_{secrets.token_urlsafe(32)}"
        self.keys.add(tenant.id, prefix, _digest(key), " ".join(scopes), label, expires)
        self.session.commit()
        return IssuedKey(key, prefix, tenant.name, scopes, expires)

    def revoke(self, prefix: str) -> ApiKey:
        key = self.keys.by_prefix(prefix.strip())
        if key is None:
            raise NotFound(f"no key with prefix {prefix!r}", code="key_not_found")
        if key.revoked_at is None:
            self.keys.revoke(key, datetime.now(UTC))
        self.session.commit()
        return key

    def listing(self, tenant_name: str | None = None) -> list[tuple[ApiKey, str]]:
        tenant_id = None
        if tenant_name is not None:
            tenant = self.tenants.by_name(tenant_name)
            if tenant is None:
                raise NotFound(f"no tenant {tenant_name!r}", code="tenant_not_found")
            tenant_id = tenant.id
        return self.keys.listing(tenant_id)

    def authenticate(self, presented: str) -> Principal:
        """The principal of a presented key, or 401 (malformed, unknown, revoked or
        expired: the answer does not say which of the last three, to a guesser)."""
        match = KEY_PATTERN.match(presented.strip())
        if not match:
            raise Unauthorized("the API key is malformed: it reads cnk_<8 hex>_<43 characters>", code="invalid_key")
        key = self.keys.by_prefix(match.group(1))
        now = datetime.now(UTC)
        if key is None or not hmac.compare_digest(key.secret_sha256, _digest(presented.strip())):
            raise Unauthorized("the API key is not valid", code="invalid_key")
        if key.revoked_at is not None or (key.expires_at is not None and key.expires_at <= now):
            raise Unauthorized("the API key has been revoked or has expired; ask your administrator for a new one",
                               code="invalid_key")
        if key.last_used_at is None or now - key.last_used_at > TOUCH_EVERY:
            self.keys.touch(key.id, now)
            self.session.commit()
        return Principal(key.tenant_id, key.prefix, frozenset(key.scopes.split()))
