"""One job's life in the jobs table, shared by both runners (the embedded process pool
and Dramatiq workers): the jobs table is the source of truth for status.

A job is claimed under a lease (``owner`` until ``lease_until``), renewed while it runs,
and finished - a record stored with ``succeeded``, or ``failed`` with a reason - only by
the owner of its lease, in one transaction: a job ends exactly once, whoever delivered
it and however often.  A job whose fit was interrupted is released to the queue.
"""

from __future__ import annotations

import logging
import os
import socket
import uuid
from dataclasses import dataclass
from datetime import datetime, timedelta

from sqlalchemy.orm import Session, sessionmaker

from app.db.models import utcnow
from app.db.repositories import JobRepository, RecordRepository, ScanRepository
from app.geometry.errors import FitFailure
from app.services.records import record_etag
from app.services.storage import ScanStore

log = logging.getLogger("calf_nurbs.jobs")


@dataclass(frozen=True)
class ClaimedJob:
    """What a fit needs: the job, its stored scan's path and format, options, placement,
    and where the upload check left the leg it cut out (app.services.placed_legs)."""

    job_id: str
    path: str
    file_format: str
    options: dict
    placement: dict | None
    tenant_id: str | None = None
    placed_leg: str | None = None


#: a claim found a job that had used up its attempts (it is now failed)
EXHAUSTED = "exhausted"
INTERNAL_ERROR_DETAIL = "the fit failed on an unexpected error; it has been logged for the service's operators"


def timeout_detail(limit_s: float) -> str:
    return f"the fit took longer than {limit_s:g} s"


def owner_name() -> str:
    """A lease owner: ``host:pid:tag`` (the pid says which process to look at; the tag
    tells two runners of one process apart)."""
    return f"{socket.gethostname()}:{os.getpid()}:{uuid.uuid4().hex[:8]}"


def lease_until(lease_s: float) -> datetime:
    return utcnow() + timedelta(seconds=lease_s)


def claim(sessions: sessionmaker[Session], store: ScanStore, owner: str, lease_s: float, max_attempts: int,
          job_id: str | None = None, per_tenant: int | None = None) -> ClaimedJob | str | None:
    """Lease the oldest claimable job (or ``job_id``) to ``owner``: a ClaimedJob, None
    when there is none (or ``job_id`` is finished or held by a live lease), or
    :data:`EXHAUSTED` when the job had been claimed ``max_attempts`` times already."""
    with sessions() as session, session.begin():
        jobs = JobRepository(session)
        job = jobs.claim_next(owner, lease_until(lease_s), job_id=job_id, per_tenant=per_tenant)
        if job is None:
            return None
        if job.attempts > max_attempts:
            jobs.fail(job.id, "worker_crashed", f"the fit was interrupted {job.attempts - 1} times (its worker "
                      "process died or was stopped); it is not tried again", owner=owner)
            return EXHAUSTED
        scan = ScanRepository(session).get(job.scan_id)
        return ClaimedJob(job.id, str(store.path_for(scan.sha256)), scan.file_format, dict(job.options), job.placement,
                          job.tenant_id, str(store.placed_leg_path(job.id)))


def renew(sessions: sessionmaker[Session], owner: str, job_ids: list[str], lease_s: float) -> None:
    with sessions() as session, session.begin():
        JobRepository(session).renew_leases(owner, job_ids, lease_until(lease_s))


def release(sessions: sessionmaker[Session], owner: str, job_id: str) -> None:
    with sessions() as session, session.begin():
        JobRepository(session).release(job_id, owner)


def succeed(sessions: sessionmaker[Session], owner: str, job_id: str, outcome: dict) -> bool:
    """Store the record and end the job, together; False (nothing stored) when the
    lease was taken over by another runner."""
    with sessions() as session:
        jobs = JobRepository(session)
        job = jobs.get(job_id)
        body = outcome["record"]
        record = RecordRepository(session).add(body, record_etag(body), "fit", job.scan_id, owner=job.tenant_id,
                                               case_ref=job.case_ref)
        if jobs.succeed(job_id, owner, record.id, outcome["stage_seconds"]):
            session.commit()
            return True
        session.rollback()
    log.warning("job %s was taken over by another runner; its record is not stored twice", job_id)
    return False


def fail(sessions: sessionmaker[Session], owner: str, job_id: str, code: str, detail: str) -> None:
    with sessions() as session, session.begin():
        JobRepository(session).fail(job_id, code, detail, owner=owner)


def conclude(sessions: sessionmaker[Session], owner: str, job_id: str, *, outcome: dict | None = None,
             failure: FitFailure | None = None, timeout_s: float | None = None) -> str | None:
    """Store how a fit ended, the one path both runners take (the embedded pool and
    Dramatiq's workers): the record of ``outcome``, the reason of ``failure``, or a
    timeout after ``timeout_s``.  Returns the job's failure code, None for a record."""
    if failure is not None:
        fail(sessions, owner, job_id, failure.reason.value, failure.detail)
        return failure.reason.value
    if timeout_s is not None:
        fail(sessions, owner, job_id, "timeout", timeout_detail(timeout_s))
        return "timeout"
    if outcome is None:
        raise ValueError("a concluded fit has an outcome, a failure or a timeout")
    succeed(sessions, owner, job_id, outcome)
    return None


def status(sessions: sessionmaker[Session], job_id: str) -> str | None:
    with sessions() as session:
        job = JobRepository(session).get(job_id)
        return None if job is None else job.status


def queued_job_ids(sessions: sessionmaker[Session]) -> list[str]:
    """Every queued job, oldest first (re-sent to the broker at an API's start-up)."""
    with sessions() as session:
        return JobRepository(session).queued_ids()
