"""Readiness: the database answers and is migrated to head, and the job runner can run."""

from __future__ import annotations

import logging

from sqlalchemy.orm import Session

from app.db.migrate import current_revision, head_revision
from app.db.repositories import ping
from app.errors import Unavailable

log = logging.getLogger("calf_nurbs.health")


def readiness(session: Session, database_url: str, runner_problem: str | None) -> str:
    """The database's migration revision when the service is ready; 503 otherwise."""
    try:
        ping(session)
        current = current_revision(database_url)
    except Exception as exc:
        log.exception("readiness: the database is not reachable")  # the cause goes to the log, not to the client
        raise Unavailable("the database is not reachable", code="database_unreachable") from exc
    if runner_problem:
        raise Unavailable(runner_problem, code="runner_unavailable")
    head = head_revision(database_url)
    if current != head:
        raise Unavailable(f"the database is at revision {current}, the code expects {head}", code="migrations_pending")
    return current
