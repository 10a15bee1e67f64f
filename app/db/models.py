"""ORM models: tenants (clinics) and their API keys; stored scans (content-addressed
within a tenant), fitting jobs, calf records, designs - each owned by one tenant."""

from __future__ import annotations

import uuid
from datetime import UTC, datetime

from sqlalchemy import JSON, BigInteger, DateTime, Float, ForeignKey, Index, Integer, String, Text, UniqueConstraint
from sqlalchemy.orm import DeclarativeBase, Mapped, mapped_column, relationship
from sqlalchemy.types import TypeDecorator


def utcnow() -> datetime:
    return datetime.now(UTC)


class UTCDateTime(TypeDecorator):
    """Timestamps stored in UTC and always read back timezone-aware (SQLite keeps no
    offset; PostgreSQL does)."""

    impl = DateTime(timezone=True)
    cache_ok = True

    def process_bind_param(self, value, dialect):
        if value is not None and value.tzinfo is not None:
            value = value.astimezone(UTC)
        return value

    def process_result_value(self, value, dialect):
        if value is not None and value.tzinfo is None:
            value = value.replace(tzinfo=UTC)
        return value


def new_id() -> str:
    return uuid.uuid4().hex


class Base(DeclarativeBase):
    pass


#: the tenant that data stored before tenants existed belongs to (migration 0004), and
#: the one an unauthenticated local service acts as
DEFAULT_TENANT_ID = "default"


class Tenant(Base):
    """A clinic (or any customer) whose data is kept apart from every other's."""

    __tablename__ = "tenants"

    id: Mapped[str] = mapped_column(String(32), primary_key=True, default=new_id)
    name: Mapped[str] = mapped_column(String(100), unique=True, nullable=False)
    created_at: Mapped[datetime] = mapped_column(UTCDateTime(), default=utcnow, nullable=False)


class ApiKey(Base):
    """An API key of a tenant: only its SHA-256 is stored; ``prefix`` (unique, shown in
    lists and logs) identifies it; ``scopes`` a space-separated subset of
    upload, read, design, admin."""

    __tablename__ = "api_keys"

    id: Mapped[str] = mapped_column(String(32), primary_key=True, default=new_id)
    tenant_id: Mapped[str] = mapped_column(ForeignKey("tenants.id", ondelete="CASCADE"), nullable=False)
    prefix: Mapped[str] = mapped_column(String(32), unique=True, nullable=False)
    secret_sha256: Mapped[str] = mapped_column(String(64), nullable=False)
    scopes: Mapped[str] = mapped_column(String(100), nullable=False)
    label: Mapped[str | None] = mapped_column(String(100))
    created_at: Mapped[datetime] = mapped_column(UTCDateTime(), default=utcnow, nullable=False)
    expires_at: Mapped[datetime | None] = mapped_column(UTCDateTime())
    revoked_at: Mapped[datetime | None] = mapped_column(UTCDateTime())
    last_used_at: Mapped[datetime | None] = mapped_column(UTCDateTime())

    __table_args__ = (Index("ix_api_keys_tenant", "tenant_id"),)


def _tenant_column() -> Mapped[str]:
    return mapped_column(ForeignKey("tenants.id", ondelete="RESTRICT"), nullable=False, default=DEFAULT_TENANT_ID)


class Scan(Base):
    """An uploaded scan file, stored once per tenant under its SHA-256 (the bytes on disk
    are shared; the row, and so access to it, is the tenant's)."""

    __tablename__ = "scans"

    id: Mapped[str] = mapped_column(String(32), primary_key=True, default=new_id)
    tenant_id: Mapped[str] = _tenant_column()
    sha256: Mapped[str] = mapped_column(String(64), nullable=False)
    size_bytes: Mapped[int] = mapped_column(BigInteger, nullable=False)
    file_format: Mapped[str] = mapped_column(String(16), nullable=False)
    media_type: Mapped[str] = mapped_column(String(100), nullable=False)
    created_at: Mapped[datetime] = mapped_column(UTCDateTime(), default=utcnow, nullable=False)

    __table_args__ = (UniqueConstraint("tenant_id", "sha256", name="uq_scans_tenant_sha256"),)


class Job(Base):
    """A fit of one scan with given options: queued -> running -> succeeded | failed.
    A running job is leased to one runner (``lease_owner`` until ``lease_expires_at``)."""

    __tablename__ = "jobs"

    id: Mapped[str] = mapped_column(String(32), primary_key=True, default=new_id)
    tenant_id: Mapped[str] = _tenant_column()
    scan_id: Mapped[str] = mapped_column(ForeignKey("scans.id", ondelete="RESTRICT"), nullable=False)
    status: Mapped[str] = mapped_column(String(16), nullable=False, default="queued")
    options: Mapped[dict] = mapped_column(JSON, nullable=False)
    placement: Mapped[dict | None] = mapped_column(JSON)  # the calf found by the upload check
    created_at: Mapped[datetime] = mapped_column(UTCDateTime(), default=utcnow, nullable=False)
    started_at: Mapped[datetime | None] = mapped_column(UTCDateTime())
    finished_at: Mapped[datetime | None] = mapped_column(UTCDateTime())
    attempts: Mapped[int] = mapped_column(default=0, nullable=False)
    error_code: Mapped[str | None] = mapped_column(String(64))
    error_detail: Mapped[str | None] = mapped_column(Text)
    stage_seconds: Mapped[dict | None] = mapped_column(JSON)
    record_id: Mapped[str | None] = mapped_column(ForeignKey("records.id", ondelete="SET NULL"))
    #: the runner that holds a running job, until when (renewed while the fit runs)
    lease_owner: Mapped[str | None] = mapped_column(String(100))
    lease_expires_at: Mapped[datetime | None] = mapped_column(UTCDateTime())
    #: the clinic's pseudonymous case reference sent with the upload (app.services.cases)
    case_ref: Mapped[str | None] = mapped_column(String(64))

    __table_args__ = (Index("ix_jobs_status_created", "status", "created_at"), Index("ix_jobs_tenant", "tenant_id"),
                      Index("ix_jobs_tenant_case", "tenant_id", "case_ref"))


class Record(Base):
    """A calf record (the JSON of app.records.codec) with a few searchable columns."""

    __tablename__ = "records"

    id: Mapped[str] = mapped_column(String(32), primary_key=True, default=new_id)
    tenant_id: Mapped[str] = _tenant_column()
    scan_id: Mapped[str | None] = mapped_column(ForeignKey("scans.id", ondelete="RESTRICT"))
    source: Mapped[str] = mapped_column(String(16), nullable=False)  # "fit" | "import"
    side: Mapped[str | None] = mapped_column(String(8))
    error_index: Mapped[float | None] = mapped_column(Float)
    etag: Mapped[str] = mapped_column(String(64), nullable=False)
    body: Mapped[dict] = mapped_column(JSON, nullable=False)
    created_at: Mapped[datetime] = mapped_column(UTCDateTime(), default=utcnow, nullable=False)
    #: the case reference of the upload the record was fitted from (or given on import)
    case_ref: Mapped[str | None] = mapped_column(String(64))

    __table_args__ = (Index("ix_records_tenant_created", "tenant_id", "created_at"),
                      Index("ix_records_tenant_case", "tenant_id", "case_ref"))


class Design(Base):
    """A stocking design made from a record, with every input needed to reproduce it."""

    __tablename__ = "designs"

    id: Mapped[str] = mapped_column(String(32), primary_key=True, default=new_id)
    tenant_id: Mapped[str] = _tenant_column()
    record_id: Mapped[str] = mapped_column(ForeignKey("records.id", ondelete="CASCADE"), nullable=False)
    inputs: Mapped[dict] = mapped_column(JSON, nullable=False)
    result: Mapped[dict] = mapped_column(JSON, nullable=False)
    etag: Mapped[str] = mapped_column(String(64), nullable=False)
    created_at: Mapped[datetime] = mapped_column(UTCDateTime(), default=utcnow, nullable=False)
    #: the record it was made from (read only: its case reference and side go to the
    #: design's view and its order; a design never changes its record)
    record: Mapped[Record] = relationship(viewonly=True)

    __table_args__ = (Index("ix_designs_record", "record_id"), Index("ix_designs_tenant", "tenant_id"))


class IdempotentRequest(Base):
    """A request sent with an ``Idempotency-Key``: what it asked (``operation`` and the
    SHA-256 ``fingerprint`` of its content) and, once done, the response it got, kept
    until ``expires_at`` so that a retry gets the same answer.  ``pending`` while the
    first request is being answered (a concurrent retry gets 409)."""

    __tablename__ = "idempotent_requests"

    id: Mapped[str] = mapped_column(String(32), primary_key=True, default=new_id)
    tenant_id: Mapped[str] = mapped_column(String(32), ForeignKey("tenants.id", ondelete="CASCADE"), nullable=False)
    key: Mapped[str] = mapped_column(String(255), nullable=False)
    operation: Mapped[str] = mapped_column(String(200), nullable=False)
    fingerprint: Mapped[str] = mapped_column(String(64), nullable=False)
    state: Mapped[str] = mapped_column(String(16), nullable=False)
    status_code: Mapped[int | None] = mapped_column(Integer)
    response_body: Mapped[dict | None] = mapped_column(JSON)
    location: Mapped[str | None] = mapped_column(String(300))
    #: the process answering a pending request (host:pid:tag), to tell a dead one
    owner: Mapped[str | None] = mapped_column(String(100))
    created_at: Mapped[datetime] = mapped_column(UTCDateTime(), default=utcnow, nullable=False)
    expires_at: Mapped[datetime] = mapped_column(UTCDateTime(), nullable=False)
    __table_args__ = (UniqueConstraint("tenant_id", "key", name="uq_idempotent_requests_tenant_key"),
                      Index("ix_idempotent_requests_expires", "expires_at"))


class SizeChartRow(Base):
    """A ready-to-wear size chart registered by a tenant (app.geometry.garment.size_charts)."""

    __tablename__ = "size_charts"

    id: Mapped[str] = mapped_column(String(32), primary_key=True, default=new_id)
    tenant_id: Mapped[str] = _tenant_column()
    product: Mapped[str] = mapped_column(String(100), nullable=False)
    stocking_type: Mapped[str] = mapped_column(String(2), nullable=False)
    body: Mapped[dict] = mapped_column(JSON, nullable=False)
    created_at: Mapped[datetime] = mapped_column(UTCDateTime(), default=utcnow, nullable=False)

    __table_args__ = (Index("ix_size_charts_tenant", "tenant_id"),)
