"""Readiness: the database answers and is migrated to head, and the job runner can run."""

from __future__ import annotations

import logging
import time

from sqlalchemy.exc import OperationalError
from sqlalchemy.orm import Session, sessionmaker

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


def wait_for_database(sessions: sessionmaker[Session], timeout_s: float, poll_s: float = 1.0) -> None:
    """Wait until the database answers, at most ``timeout_s`` seconds, then let its last
    error through: a service started beside its database (compose, a pod) can come up
    before the database's name resolves or its server accepts connections, and would
    otherwise exit at once (a CI run's container saw "failed to resolve host 'db'"
    seconds after the database was healthy).  An embedded SQLite answers at once."""
    deadline = time.monotonic() + timeout_s
    while True:
        try:
            with sessions() as session:
                ping(session)
            return
        except OperationalError:
            if time.monotonic() >= deadline:
                raise
            log.warning("the database does not answer yet: trying again for up to %.0f s",
                        max(deadline - time.monotonic(), 0.0))
            time.sleep(poll_s)
