"""Uploads become stored scans and queued jobs; job views."""

from __future__ import annotations

from collections.abc import Callable

from sqlalchemy.exc import IntegrityError
from sqlalchemy.orm import Session

from app.db.models import Job, Scan
from app.db.repositories import JobRepository, RecordRepository, ScanRepository
from app.errors import FAILURE_TITLES, PROBLEM_TYPE_PREFIX, NotFound
from app.geometry.errors import FailureReason
from app.services.fair_share import too_many_jobs
from app.services.storage import ScanStore
from app.services.uploads import ReceivedUpload

#: a failed job's title where its stored code has none
JOB_FAILED_TITLE = "The fit could not be completed"


class JobService:
    """Scans and jobs of one tenant: the same bytes are stored once per tenant."""

    def __init__(self, session: Session, tenant_id: str):
        self.session = session
        self.scans = ScanRepository(session, tenant_id)
        self.jobs = JobRepository(session, tenant_id)

    def submit(self, upload: ReceivedUpload, options: dict, store: ScanStore, placement: dict | None = None,
               before_commit: Callable[[Job, Scan, bool], None] | None = None,
               case_ref: str | None = None) -> tuple[Job, Scan, bool]:
        """Store the scan once (content-addressed) and queue a job; commits.
        ``before_commit(job, scan, reused)`` runs in the job's transaction (the
        idempotent answer is stored with the job).

        Returns (job, scan, reused) - reused when the same bytes were already stored.
        """
        scan = self.scans.by_sha256(upload.sha256)
        reused = scan is not None
        newly_stored = False
        if scan is None:
            _, newly_stored = store.commit(upload.temp_path, upload.sha256)
            try:
                scan = self.scans.add(upload.sha256, upload.size_bytes, upload.file_format, upload.media_type)
                self.session.commit()
            except IntegrityError:  # the same bytes arrived concurrently: use that row
                self.session.rollback()
                scan = self.scans.by_sha256(upload.sha256)
                reused = True
                if scan is None:
                    if newly_stored:
                        store.remove(upload.sha256)
                    raise
        elif not store.exists(upload.sha256):
            store.commit(upload.temp_path, upload.sha256)  # the stored file went missing: these bytes restore it
        else:
            upload.discard()
        job = self.jobs.add(scan.id, options, placement, case_ref)
        if before_commit is not None:
            before_commit(job, scan, reused)
        self.session.commit()
        return job, scan, reused

    def ensure_capacity(self, limit: int) -> None:
        """429 ``too_many_jobs`` when the tenant has ``limit`` jobs queued or running."""
        if self.jobs.count_active() >= limit:
            raise too_many_jobs(limit)

    def usage(self, settings) -> dict:
        """The tenant's jobs by status and the bounds of app.services.fair_share."""
        counts = self.jobs.count_by_status()
        return {
            "jobs": {status: counts.get(status, 0) for status in ("queued", "running", "succeeded", "failed")},
            "limits": {
                "max_active_jobs": settings.tenant_max_jobs,
                "max_concurrent_checks": settings.checks_per_tenant,
                "max_concurrent_fits": settings.fits_per_tenant,
                "uploads_per_minute": settings.upload_rate_limit,
                "requests_per_minute": settings.rate_limit,
                "max_upload_bytes": settings.max_upload_bytes,
                "max_json_bytes": settings.max_json_bytes,
            },
        }

    def get(self, job_id: str) -> tuple[Job, Scan]:
        job = self.jobs.get(job_id)
        if job is None:
            raise NotFound(f"no job {job_id!r}", code="job_not_found")
        return job, self.scans.get(job.scan_id)

    def view(self, job_id: str) -> dict:
        """The job's view, with its record's warnings once it has one (a given side that
        the foot contradicts, the surface off the skin...: said where the uploader looks)."""
        job, scan = self.get(job_id)
        record = RecordRepository(self.session, self.jobs.tenant_id).get(job.record_id) if job.record_id else None
        return job_view(job, scan, warnings=list((record.body or {}).get("warnings") or []) if record else [])


def job_status_counts(session: Session) -> dict[str, int]:
    """Jobs of every tenant by status (the service's own metrics, no tenant shown)."""
    return JobRepository(session).count_by_status()


def job_view(job: Job, scan: Scan, reused: bool | None = None, warnings: list[str] | None = None) -> dict:
    error = None
    if job.error_code:
        try:  # a code stored by an older or newer release may not be a reason of this one
            title = FAILURE_TITLES.get(FailureReason(job.error_code), JOB_FAILED_TITLE)
        except ValueError:
            title = JOB_FAILED_TITLE
        error = {"type": PROBLEM_TYPE_PREFIX + job.error_code, "code": job.error_code, "title": title, "detail": job.error_detail or ""}
    links = {"self": f"/api/v1/jobs/{job.id}"}
    if job.record_id:
        links["record"] = f"/api/v1/records/{job.record_id}"
    return {
        "id": job.id,
        "status": job.status,
        "scan_id": scan.id,
        "scan_sha256": scan.sha256,
        "scan_reused": reused,
        "options": job.options,
        "created_at": job.created_at,
        "started_at": job.started_at,
        "finished_at": job.finished_at,
        "attempts": job.attempts,
        "stage_seconds": job.stage_seconds,
        "error": error,
        "record_id": job.record_id,
        "case_ref": job.case_ref,
        "warnings": warnings or [],
        "links": links,
    }
