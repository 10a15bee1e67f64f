"""Repositories: every query of the service lives here (routers and services call these).

Tenant scoping: a repository made with a ``tenant_id`` sees and writes only that
tenant's rows (another tenant's id reads as absent, so the API answers 404 and never
reveals that it exists); ``tenant_id=None`` is the job runner's system view, which
works across tenants and writes each result under its job's tenant."""

from __future__ import annotations

from datetime import datetime

from sqlalchemy import and_, delete, func, or_, select, text, update
from sqlalchemy.orm import Session, aliased

from app.db.models import ApiKey, Design, IdempotentRequest, Job, Record, Scan, SizeChartRow, Tenant, utcnow

JOB_QUEUED, JOB_RUNNING, JOB_SUCCEEDED, JOB_FAILED = "queued", "running", "succeeded", "failed"


def _inserted(session: Session, row):
    """``row`` added and flushed (its defaults and id filled in)."""
    session.add(row)
    session.flush()
    return row


def count_rows(session: Session, model) -> int:
    """Number of rows of a model's table."""
    return session.scalar(select(func.count()).select_from(model)) or 0


class _Owned:
    """A repository of rows owned by a tenant (see the module docstring)."""

    model = None

    def __init__(self, session: Session, tenant_id: str | None = None):
        self.session = session
        self.tenant_id = tenant_id

    def _scoped(self, query, model=None):
        """``query`` limited to the tenant's rows of ``model`` (the repository's own by default)."""
        model = model or self.model
        return query if self.tenant_id is None else query.where(model.tenant_id == self.tenant_id)

    def get(self, row_id: str):
        row = self.session.get(self.model, row_id)
        if row is None or (self.tenant_id is not None and row.tenant_id != self.tenant_id):
            return None
        return row

    def _owner(self, owner: str | None) -> str:
        tenant = owner or self.tenant_id
        if tenant is None:
            raise ValueError("a row needs its tenant")
        return tenant


class TenantRepository:
    def __init__(self, session: Session):
        self.session = session

    def by_name(self, name: str) -> Tenant | None:
        return self.session.scalar(select(Tenant).where(Tenant.name == name))

    def get(self, tenant_id: str) -> Tenant | None:
        return self.session.get(Tenant, tenant_id)

    def add(self, name: str) -> Tenant:
        return _inserted(self.session, Tenant(name=name))

    def all(self) -> list[Tenant]:
        return list(self.session.scalars(select(Tenant).order_by(Tenant.name)))


class ApiKeyRepository:
    def __init__(self, session: Session):
        self.session = session

    def add(self, tenant_id: str, prefix: str, secret_sha256: str, scopes: str, label: str | None,
            expires_at: datetime | None) -> ApiKey:
        return _inserted(self.session, ApiKey(tenant_id=tenant_id, prefix=prefix, secret_sha256=secret_sha256,
                                              scopes=scopes, label=label, expires_at=expires_at))

    def by_prefix(self, prefix: str) -> ApiKey | None:
        return self.session.scalar(select(ApiKey).where(ApiKey.prefix == prefix))

    def listing(self, tenant_id: str | None = None) -> list[tuple[ApiKey, str]]:
        """(key, tenant name) pairs, oldest first; one tenant's or all."""
        query = select(ApiKey, Tenant.name).join(Tenant, Tenant.id == ApiKey.tenant_id).order_by(ApiKey.created_at)
        if tenant_id is not None:
            query = query.where(ApiKey.tenant_id == tenant_id)
        return [(key, name) for key, name in self.session.execute(query).all()]

    def touch(self, key_id: str, when: datetime) -> None:
        self.session.execute(update(ApiKey).where(ApiKey.id == key_id).values(last_used_at=when))

    def revoke(self, key: ApiKey, when: datetime) -> None:
        key.revoked_at = when
        self.session.flush()


class ScanRepository(_Owned):
    model = Scan

    def by_sha256(self, sha256: str) -> Scan | None:
        return self.session.scalar(self._scoped(select(Scan).where(Scan.sha256 == sha256)))

    def add(self, sha256: str, size_bytes: int, file_format: str, media_type: str) -> Scan:
        return _inserted(self.session, Scan(tenant_id=self._owner(None), sha256=sha256, size_bytes=size_bytes,
                                            file_format=file_format, media_type=media_type))

    def count(self) -> int:
        return count_rows(self.session, Scan)


class JobRepository(_Owned):
    model = Job

    def add(self, scan_id: str, options: dict, placement: dict | None = None, case_ref: str | None = None) -> Job:
        return _inserted(self.session, Job(tenant_id=self._owner(None), scan_id=scan_id, options=options,
                                           placement=placement, status=JOB_QUEUED, case_ref=case_ref))

    def claim_next(self, owner: str, lease_until: datetime, job_id: str | None = None,
                   per_tenant: int | None = None) -> Job | None:
        """Atomically lease the next claimable job (or the job ``job_id``) to ``owner``
        and return it: a queued job, or a running one whose lease has expired (its
        runner died).  Next: the oldest job of the tenant with the fewest live fits
        running, of a tenant with fewer than ``per_tenant`` running (app.services.fair_share).

        PostgreSQL: ``FOR UPDATE SKIP LOCKED`` lets several runners claim concurrently;
        SQLite serializes writers, and the conditional UPDATE re-checks the condition.
        """
        now = utcnow()
        # a running job without a lease was left by a runner from before leases: expired
        lapsed = or_(Job.lease_expires_at.is_(None), Job.lease_expires_at < now)
        claimable = or_(Job.status == JOB_QUEUED, and_(Job.status == JOB_RUNNING, lapsed))
        # fair share: the tenant with the fewest fits running goes first, then the oldest job
        other = aliased(Job)
        running = (select(func.count()).select_from(other)
                   .where(other.tenant_id == Job.tenant_id, other.status == JOB_RUNNING, other.lease_expires_at >= now)
                   .scalar_subquery())
        query = select(Job).where(claimable).order_by(running, Job.created_at, Job.id).limit(1)
        if per_tenant is not None:
            query = query.where(running < per_tenant)
        if job_id is not None:
            query = query.where(Job.id == job_id)
        if self.session.bind.dialect.name == "postgresql":
            query = query.with_for_update(skip_locked=True)
        job = self.session.scalar(query)
        if job is None:
            return None
        claimed = self.session.execute(
            update(Job)
            .where(Job.id == job.id, claimable)
            .values(status=JOB_RUNNING, started_at=now, attempts=Job.attempts + 1, lease_owner=owner,
                    lease_expires_at=lease_until)
            .execution_options(synchronize_session=False)
        )
        if claimed.rowcount != 1:
            return None
        self.session.flush()
        self.session.refresh(job)
        return job

    def count_active(self) -> int:
        """Jobs queued or running (the tenant's, or every tenant's for the system view)."""
        query = self._scoped(select(func.count()).select_from(Job).where(Job.status.in_((JOB_QUEUED, JOB_RUNNING))))
        return self.session.scalar(query) or 0

    def of_scans(self, scan_ids: list[str]) -> list[Job]:
        """The jobs of these scans, newest first."""
        if not scan_ids:
            return []
        query = self._scoped(select(Job).where(Job.scan_id.in_(scan_ids)))
        return list(self.session.scalars(query.order_by(Job.created_at.desc(), Job.id.desc())))

    def queued_ids(self) -> list[str]:
        return list(self.session.scalars(select(Job.id).where(Job.status == JOB_QUEUED).order_by(Job.created_at, Job.id)))

    def renew_leases(self, owner: str, job_ids: list[str], lease_until: datetime) -> int:
        """Extend the leases ``owner`` still holds on ``job_ids``."""
        if not job_ids:
            return 0
        result = self.session.execute(
            update(Job).where(Job.id.in_(job_ids), Job.lease_owner == owner, Job.status == JOB_RUNNING)
            .values(lease_expires_at=lease_until).execution_options(synchronize_session=False))
        return result.rowcount or 0

    def release(self, job_id: str, owner: str) -> bool:
        """Put a job whose fit was interrupted back in the queue (if ``owner`` holds it)."""
        result = self.session.execute(
            update(Job).where(Job.id == job_id, Job.lease_owner == owner, Job.status == JOB_RUNNING)
            .values(status=JOB_QUEUED, started_at=None, lease_owner=None, lease_expires_at=None))
        return result.rowcount == 1

    def succeed(self, job_id: str, owner: str, record_id: str, stage_seconds: dict) -> bool:
        """Finish a job ``owner`` still holds; False when another runner has taken it
        over (the caller then rolls back its record: a job ends exactly once)."""
        result = self.session.execute(
            update(Job)
            .where(Job.id == job_id, Job.lease_owner == owner, Job.status == JOB_RUNNING)
            .values(status=JOB_SUCCEEDED, finished_at=utcnow(), record_id=record_id, stage_seconds=stage_seconds,
                    lease_expires_at=None)
        )
        return result.rowcount == 1

    def fail(self, job_id: str, code: str, detail: str, owner: str | None = None) -> bool:
        """Fail a job (one ``owner`` holds, when given)."""
        query = update(Job).where(Job.id == job_id)
        if owner is not None:
            query = query.where(Job.lease_owner == owner, Job.status == JOB_RUNNING)
        result = self.session.execute(query.values(status=JOB_FAILED, finished_at=utcnow(), error_code=code,
                                                   error_detail=detail, lease_expires_at=None))
        return result.rowcount == 1

    def count_by_status(self) -> dict[str, int]:
        """Jobs by status: the tenant's, or every tenant's for the system view."""
        rows = self.session.execute(self._scoped(select(Job.status, func.count())).group_by(Job.status)).all()
        return {status: count for status, count in rows}

    def count(self) -> int:
        return count_rows(self.session, Job)


class RecordRepository(_Owned):
    model = Record

    def add(self, body: dict, etag: str, source: str, scan_id: str | None, owner: str | None = None,
            case_ref: str | None = None) -> Record:
        """A new record; ``owner`` is the tenant when the repository has none (the runner)."""
        return _inserted(self.session, Record(
            tenant_id=self._owner(owner),
            case_ref=case_ref,
            body=body,
            etag=etag,
            source=source,
            scan_id=scan_id,
            side=body.get("side"),
            error_index=(body.get("fit") or {}).get("error_index"),
        ))

    def page(self, limit: int, after: tuple[datetime, str] | None, side: str | None = None,
             since: datetime | None = None, until: datetime | None = None, case_ref: str | None = None) -> list[Record]:
        """Newest first, keyset pagination on (created_at, id); optionally only one side
        ("left", "right", or "unknown" for none), one case, and created in [since, until)."""
        query = self._scoped(select(Record)).order_by(Record.created_at.desc(), Record.id.desc()).limit(limit)
        if case_ref is not None:
            query = query.where(Record.case_ref == case_ref)
        if side is not None:
            query = query.where(Record.side.is_(None) if side == "unknown" else Record.side == side)
        if since is not None:
            query = query.where(Record.created_at >= since)
        if until is not None:
            query = query.where(Record.created_at < until)
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


class DesignRepository(_Owned):
    model = Design

    def add(self, record_id: str, inputs: dict, result: dict, etag: str) -> Design:
        return _inserted(self.session, Design(tenant_id=self._owner(None), record_id=record_id, inputs=inputs, result=result, etag=etag))

    def for_record(self, record_id: str) -> list[Design]:
        query = self._scoped(select(Design).where(Design.record_id == record_id)).order_by(Design.created_at)
        return list(self.session.scalars(query))


def ping(session: Session) -> None:
    session.execute(text("SELECT 1"))


class IdempotentRequestRepository(_Owned):
    model = IdempotentRequest

    def by_key(self, key: str) -> IdempotentRequest | None:
        return self.session.scalar(self._scoped(select(IdempotentRequest).where(IdempotentRequest.key == key)))

    def reserve(self, key: str, operation: str, fingerprint: str, expires_at: datetime, owner: str) -> IdempotentRequest:
        """Insert a pending row held by ``owner``; a concurrent one with the same key raises IntegrityError."""
        return _inserted(self.session, IdempotentRequest(tenant_id=self._owner(None), key=key, operation=operation,
                                                         fingerprint=fingerprint, state="pending", expires_at=expires_at,
                                                         owner=owner))

    def complete(self, row_id: str, status_code: int, body: dict, location: str | None) -> None:
        self.session.execute(update(IdempotentRequest).where(IdempotentRequest.id == row_id).values(
            state="done", status_code=status_code, response_body=body, location=location))

    def remove(self, row_id: str) -> None:
        self.session.execute(delete(IdempotentRequest).where(IdempotentRequest.id == row_id))

    def remove_expired(self, now: datetime) -> int:
        result = self.session.execute(self._scoped(delete(IdempotentRequest)).where(IdempotentRequest.expires_at < now))
        return result.rowcount or 0


class ErasureRepository(_Owned):
    """What erasing a scan or a case removes, found and deleted in the caller's
    transaction (app.services.erasure owns it)."""

    model = Scan

    def jobs_of_scan(self, scan_id: str) -> list[Job]:
        return list(self.session.scalars(self._scoped(select(Job).where(Job.scan_id == scan_id), Job)))

    def records_of_scan(self, scan_id: str) -> list[Record]:
        return list(self.session.scalars(self._scoped(select(Record).where(Record.scan_id == scan_id), Record)))

    def jobs_of_case(self, case_ref: str) -> list[Job]:
        return list(self.session.scalars(self._scoped(select(Job).where(Job.case_ref == case_ref), Job)))

    def records_of_case(self, case_ref: str) -> list[Record]:
        return list(self.session.scalars(self._scoped(select(Record).where(Record.case_ref == case_ref), Record)))

    def scans_only_of_case(self, scan_ids: set[str], case_ref: str) -> list[Scan]:
        """The scans among ``scan_ids`` that no job or record of another case (or of none) uses."""
        if not scan_ids:
            return []
        shared = set(self.session.scalars(select(Job.scan_id).where(
            Job.scan_id.in_(scan_ids), Job.case_ref.is_distinct_from(case_ref))))
        shared |= set(self.session.scalars(select(Record.scan_id).where(
            Record.scan_id.in_(scan_ids), Record.case_ref.is_distinct_from(case_ref))))
        return list(self.session.scalars(self._scoped(select(Scan).where(Scan.id.in_(scan_ids - shared)))))

    def design_ids_of(self, record_ids: list[str]) -> list[str]:
        if not record_ids:
            return []
        return list(self.session.scalars(select(Design.id).where(Design.record_id.in_(record_ids))))

    def remove(self, scan_ids: list[str], job_ids: list[str], record_ids: list[str], design_ids: list[str]) -> dict[str, int]:
        """Delete the rows named and the idempotent answers that point at them (their
        Location is the job, record or design); returns the rows removed per kind."""
        locations = ([f"/api/v1/jobs/{i}" for i in job_ids] + [f"/api/v1/records/{i}" for i in record_ids]
                     + [f"/api/v1/designs/{i}" for i in design_ids])
        removed = {"idempotency_entries": 0, "designs": 0, "jobs": 0, "records": 0, "scans": 0}
        if locations:
            removed["idempotency_entries"] = self.session.execute(self._scoped(delete(IdempotentRequest).where(
                IdempotentRequest.location.in_(locations)), IdempotentRequest)).rowcount or 0
        if design_ids:
            removed["designs"] = self.session.execute(delete(Design).where(Design.id.in_(design_ids))).rowcount or 0
        if job_ids:
            removed["jobs"] = self.session.execute(delete(Job).where(Job.id.in_(job_ids))).rowcount or 0
        if record_ids:
            self.session.execute(update(Job).where(Job.record_id.in_(record_ids)).values(record_id=None))
            removed["records"] = self.session.execute(delete(Record).where(Record.id.in_(record_ids))).rowcount or 0
        if scan_ids:
            removed["scans"] = self.session.execute(delete(Scan).where(Scan.id.in_(scan_ids))).rowcount or 0
        self.session.flush()
        return removed

    def sha256_still_stored(self, sha256: str) -> bool:
        """Whether any tenant's scan row still names these bytes (the store is content-addressed)."""
        return self.session.scalar(select(func.count()).select_from(Scan).where(Scan.sha256 == sha256)) > 0


class SizeChartRepository(_Owned):
    model = SizeChartRow

    def add(self, product: str, stocking_type: str, body: dict) -> SizeChartRow:
        return _inserted(self.session, SizeChartRow(tenant_id=self._owner(None), product=product,
                                                    stocking_type=stocking_type, body=body))

    def all(self) -> list[SizeChartRow]:
        return list(self.session.scalars(self._scoped(select(SizeChartRow)).order_by(SizeChartRow.created_at)))
