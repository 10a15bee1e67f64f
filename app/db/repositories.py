"""Repositories: every query of the service lives here (routers and services call these)."""

from __future__ import annotations

from datetime import datetime

from sqlalchemy import delete, func, select, text, update
from sqlalchemy.orm import Session

from app.db.models import Design, Job, Record, Scan, utcnow

JOB_QUEUED, JOB_RUNNING, JOB_SUCCEEDED, JOB_FAILED = "queued", "running", "succeeded", "failed"


def count_rows(session: Session, model) -> int:
    """Number of rows of a model's table."""
    return session.scalar(select(func.count()).select_from(model)) or 0


class ScanRepository:
    def __init__(self, session: Session):
        self.session = session

    def by_sha256(self, sha256: str) -> Scan | None:
        return self.session.scalar(select(Scan).where(Scan.sha256 == sha256))

    def get(self, scan_id: str) -> Scan | None:
        return self.session.get(Scan, scan_id)

    def add(self, sha256: str, size_bytes: int, file_format: str, media_type: str) -> Scan:
        scan = Scan(sha256=sha256, size_bytes=size_bytes, file_format=file_format, media_type=media_type)
        self.session.add(scan)
        self.session.flush()
        return scan

    def count(self) -> int:
        return count_rows(self.session, Scan)


class JobRepository:
    def __init__(self, session: Session):
        self.session = session

    def add(self, scan_id: str, options: dict, placement: dict | None = None) -> Job:
        job = Job(scan_id=scan_id, options=options, placement=placement, status=JOB_QUEUED)
        self.session.add(job)
        self.session.flush()
        return job

    def get(self, job_id: str) -> Job | None:
        return self.session.get(Job, job_id)

    def claim_next(self) -> Job | None:
        """Atomically move the oldest queued job to running and return it.

        PostgreSQL: ``FOR UPDATE SKIP LOCKED`` lets several runners claim concurrently;
        SQLite serializes writers, and the conditional UPDATE re-checks the status.
        """
        query = select(Job).where(Job.status == JOB_QUEUED).order_by(Job.created_at, Job.id).limit(1)
        if self.session.bind.dialect.name == "postgresql":
            query = query.with_for_update(skip_locked=True)
        job = self.session.scalar(query)
        if job is None:
            return None
        claimed = self.session.execute(
            update(Job)
            .where(Job.id == job.id, Job.status == JOB_QUEUED)
            .values(status=JOB_RUNNING, started_at=utcnow(), attempts=Job.attempts + 1)
        )
        if claimed.rowcount != 1:
            return None
        self.session.flush()
        self.session.refresh(job)
        return job

    def requeue_unfinished(self) -> int:
        """Jobs left running by a crash go back to the queue (called at start-up)."""
        result = self.session.execute(
            update(Job).where(Job.status == JOB_RUNNING).values(status=JOB_QUEUED, started_at=None)
        )
        return result.rowcount or 0

    def succeed(self, job_id: str, record_id: str, stage_seconds: dict) -> None:
        self.session.execute(
            update(Job)
            .where(Job.id == job_id)
            .values(status=JOB_SUCCEEDED, finished_at=utcnow(), record_id=record_id, stage_seconds=stage_seconds)
        )

    def fail(self, job_id: str, code: str, detail: str) -> None:
        self.session.execute(
            update(Job)
            .where(Job.id == job_id)
            .values(status=JOB_FAILED, finished_at=utcnow(), error_code=code, error_detail=detail)
        )

    def count_by_status(self) -> dict[str, int]:
        rows = self.session.execute(select(Job.status, func.count()).group_by(Job.status)).all()
        return {status: count for status, count in rows}

    def count(self) -> int:
        return count_rows(self.session, Job)


class RecordRepository:
    def __init__(self, session: Session):
        self.session = session

    def add(self, body: dict, etag: str, source: str, scan_id: str | None) -> Record:
        record = Record(
            body=body,
            etag=etag,
            source=source,
            scan_id=scan_id,
            side=body.get("side"),
            error_index=(body.get("fit") or {}).get("error_index"),
        )
        self.session.add(record)
        self.session.flush()
        return record

    def get(self, record_id: str) -> Record | None:
        return self.session.get(Record, record_id)

    def page(self, limit: int, after: tuple[datetime, str] | None) -> list[Record]:
        """Newest first, keyset pagination on (created_at, id)."""
        query = select(Record).order_by(Record.created_at.desc(), Record.id.desc()).limit(limit)
        if after is not None:
            created, record_id = after
            query = query.where(
                (Record.created_at < created) | ((Record.created_at == created) & (Record.id < record_id))
            )
        return list(self.session.scalars(query))

    def delete(self, record: Record) -> None:
        """Delete a record and the designs made from it (derived data)."""
        self.session.execute(update(Job).where(Job.record_id == record.id).values(record_id=None))
        self.session.execute(delete(Design).where(Design.record_id == record.id))
        self.session.delete(record)
        self.session.flush()

    def count(self) -> int:
        return count_rows(self.session, Record)


class DesignRepository:
    def __init__(self, session: Session):
        self.session = session

    def add(self, record_id: str, inputs: dict, result: dict, etag: str) -> Design:
        design = Design(record_id=record_id, inputs=inputs, result=result, etag=etag)
        self.session.add(design)
        self.session.flush()
        return design

    def get(self, design_id: str) -> Design | None:
        return self.session.get(Design, design_id)

    def for_record(self, record_id: str) -> list[Design]:
        return list(self.session.scalars(select(Design).where(Design.record_id == record_id).order_by(Design.created_at)))


def ping(session: Session) -> None:
    session.execute(text("SELECT 1"))
