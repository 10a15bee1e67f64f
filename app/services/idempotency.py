"""``Idempotency-Key`` on uploads and on design creation (after the IETF HTTPAPI draft
"The Idempotency-Key HTTP Header Field").

A client that is not sure its request arrived (a timeout, a dropped connection) sends it
again with the same key:

- the first request with a key reserves it (``pending``); its 2xx response is stored
  and the key is kept for CALF_IDEMPOTENCY_HOURS;
- a retry with the same key and the same content gets the stored response again (the
  same job, the same design: nothing is done twice), marked ``Idempotent-Replayed: true``;
- the same key with other content (other bytes, other options, another record or
  design request) answers 409 ``idempotency_key_reused``: a key names one request;
- a retry while the first is still being answered answers 409
  ``idempotency_key_in_use`` with Retry-After.  A reservation whose owner process has
  died (this host: its pid is gone; :mod:`app.services.process_owner`) is taken over at
  once, so the retry after a crash does the work; one held by another host's process is
  taken over after ``hold_s`` (the longest a first request can take: the upload check's
  time limit and a margin);
- the stored answer is written in the same transaction as the work it answers (the
  job, the design): a crash leaves both or neither, so a retry never does it twice;
- a first request that fails (4xx) frees its key: the retry is answered afresh.

Keys are per tenant: two clinics may use the same key for different requests.
"""

from __future__ import annotations

import hashlib
import json
import re
from collections.abc import Callable
from dataclasses import dataclass
from datetime import timedelta

from sqlalchemy.exc import IntegrityError
from sqlalchemy.orm import Session

from app.db.models import utcnow
from app.db.repositories import IdempotentRequestRepository
from app.errors import BadRequest, Conflict
from app.services.process_owner import owner_is_dead, this_process

#: what a route's ``respond`` gets: ``stage(status, body, location)`` writes the answer to
#: the request's session for the service to commit with its work (None without a key)
Stage = Callable[[int, dict, "str | None"], None]


#: printable ASCII without spaces, as the draft's examples; at most 255
KEY_PATTERN = re.compile(r"^[\x21-\x7e]{1,255}$")
#: a pending reservation without an owner (from before owners were recorded) this old
#: was left by a request that died
PENDING_TAKEOVER = timedelta(minutes=15)


@dataclass(frozen=True)
class Replay:
    """The stored first response to a key."""

    status_code: int
    body: dict
    location: str | None


@dataclass(frozen=True)
class Reservation:
    """A key reserved for the request now being answered (``finish`` or ``abandon`` it)."""

    row_id: str


def fingerprint(content: dict) -> str:
    """SHA-256 of a request's content, as canonical JSON."""
    return hashlib.sha256(json.dumps(content, sort_keys=True, separators=(",", ":"), default=str).encode()).hexdigest()


class IdempotencyService:
    def __init__(self, session: Session, tenant_id: str, keep_hours: float, hold_s: float = 120.0):
        self.session = session
        self.requests = IdempotentRequestRepository(session, tenant_id)
        self.keep = timedelta(hours=keep_hours)
        self.hold = timedelta(seconds=hold_s)

    def _abandoned(self, row, now) -> bool:
        """Was this pending reservation left by a request that died?"""
        dead = owner_is_dead(row.owner)
        if dead:
            return True
        # alive here (a request that leaked its reservation), or on another host: by age
        age = now - row.created_at
        return age >= (self.hold if dead is None and row.owner else PENDING_TAKEOVER)

    def begin(self, key: str, operation: str, content_sha256: str) -> Replay | Reservation:
        """The stored response to replay, or a reservation of ``key``; commits.  409 for a
        key used with other content, or one whose first request is still running."""
        if not KEY_PATTERN.match(key):
            raise BadRequest("the Idempotency-Key must be 1 to 255 printable ASCII characters without spaces "
                             "(a UUID is a good key)", code="invalid_idempotency_key")
        now = utcnow()
        self.requests.remove_expired(now)
        row = self.requests.by_key(key)
        if row is not None and (row.operation != operation or row.fingerprint != content_sha256):
            self.session.commit()
            raise Conflict("this Idempotency-Key was already used for a different request (other content or another "
                           "operation); use a new key for a new request", code="idempotency_key_reused")
        if row is not None and row.state == "done":
            self.session.commit()
            return Replay(row.status_code, row.response_body, row.location)
        if row is not None and not self._abandoned(row, now):
            self.session.commit()
            error = Conflict("a request with this Idempotency-Key is still being answered; retry in a moment",
                             code="idempotency_key_in_use")
            error.headers = {"Retry-After": "1"}
            raise error
        if row is not None:  # left pending by a request that died: take it over
            self.requests.remove(row.id)
        try:
            reserved = self.requests.reserve(key, operation, content_sha256, now + self.keep, this_process())
            self.session.commit()
        except IntegrityError:  # the same key arrived concurrently: that request goes first
            self.session.rollback()
            return self.begin(key, operation, content_sha256)
        return Reservation(reserved.id)

    def finish(self, reservation: Reservation, status_code: int, body: dict, location: str | None) -> None:
        self.requests.complete(reservation.row_id, status_code, body, location)
        self.session.commit()

    def stage(self, reservation: Reservation, status_code: int, body: dict, location: str | None) -> None:
        """Write the answer into the session without committing: the service that does
        the work commits it with the work, in one transaction."""
        self.requests.complete(reservation.row_id, status_code, body, location)

    def abandon(self, reservation: Reservation) -> None:
        self.session.rollback()
        self.requests.remove(reservation.row_id)
        self.session.commit()
