"""Erasure: a scan, or a whole case, removed with everything made from it.

Scans are health data.  Erasing a scan removes, in one database transaction, the scan's
row, its jobs, the records fitted from it, the designs made from those records and the
idempotent answers that point at any of them; then the stored files: the leg the
upload check cut out for a job still queued, and the scan's file (the store is
content-addressed: the file goes when no tenant's scan row names its bytes any more).
The file is removed after the commit: were it removed first and the commit fail, rows
would point at a missing file; this way a crash between the two leaves only an orphan
file, which `ScanStore` never serves (no row names it) and the next erasure or upload
of those bytes settles.

Erasing a case removes the case's records (fitted or imported) and jobs, with their
designs and idempotent answers, and every scan all of whose jobs and records belong to
the case (a scan another case also used stays, without this case's rows).

A scan whose job is running is not erased (409 job_running): the fit would write its
record after the erasure.  Queued jobs are erased with the scan and never run.
"""

from __future__ import annotations

from dataclasses import dataclass

from sqlalchemy.orm import Session

from app.db.models import Job, Record
from app.db.repositories import JOB_RUNNING, ErasureRepository, ScanRepository
from app.errors import Conflict, NotFound
from app.services.cases import validate_case_ref
from app.services.storage import ScanStore


@dataclass(frozen=True)
class ErasureReport:
    """What an erasure removed: rows per kind and stored files."""

    scans: int
    jobs: int
    records: int
    designs: int
    idempotency_entries: int
    files: int


class ErasureService:
    def __init__(self, session: Session, tenant_id: str, store: ScanStore):
        self.session = session
        self.store = store
        self.scans = ScanRepository(session, tenant_id)
        self.erasure = ErasureRepository(session, tenant_id)

    def erase_scan(self, scan_id: str) -> ErasureReport:
        scan = self.scans.get(scan_id)
        if scan is None:
            raise NotFound(f"no scan {scan_id!r}", code="scan_not_found")
        jobs = self.erasure.jobs_of_scan(scan.id)
        records = self.erasure.records_of_scan(scan.id)
        return self._erase([(scan.id, scan.sha256)], jobs, records)

    def erase_case(self, case_ref: str) -> ErasureReport:
        case_ref = validate_case_ref(case_ref) or ""
        jobs = self.erasure.jobs_of_case(case_ref)
        records = self.erasure.records_of_case(case_ref)
        if not jobs and not records:
            raise NotFound("no records or jobs with this case reference", code="case_not_found")
        used = {j.scan_id for j in jobs} | {r.scan_id for r in records if r.scan_id}
        scans = [(s.id, s.sha256) for s in self.erasure.scans_only_of_case(used, case_ref)]
        return self._erase(scans, jobs, records)

    def _erase(self, scans: list[tuple[str, str]], jobs: list[Job], records: list[Record]) -> ErasureReport:
        running = [j for j in jobs if j.status == JOB_RUNNING]
        if running:
            raise Conflict("a fitting job of this scan is running; erase it once the job has ended "
                           f"(GET /api/v1/jobs/{running[0].id})", code="job_running")
        record_ids = sorted({r.id for r in records})
        design_ids = self.erasure.design_ids_of(record_ids)
        removed = self.erasure.remove([s for s, _ in scans], sorted({j.id for j in jobs}), record_ids, design_ids)
        self.session.commit()
        # after the commit (module docstring): the legs the upload checks cut out for
        # queued jobs (app.services.placed_legs), then the scans no row names any more
        files = self.store.remove_placed_legs(sorted({j.id for j in jobs}))
        for _, sha256 in scans:
            if not self.erasure.sha256_still_stored(sha256) and self.store.exists(sha256):
                self.store.remove(sha256)
                files += 1
        return ErasureReport(files=files, **removed)
