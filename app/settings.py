"""Service settings (pydantic-settings, environment prefix ``CALF_``)."""

from __future__ import annotations

from functools import lru_cache
from pathlib import Path
from typing import Literal

from pydantic import Field
from pydantic_settings import BaseSettings, SettingsConfigDict

#: addresses only this machine can reach
LOCAL_HOSTS = ("127.0.0.1", "::1", "localhost")


class Settings(BaseSettings):
    """Everything configurable, with the embedded defaults (SQLite under ./var, an
    in-process pool of fitting workers).

    CALF_DATA_DIR        data directory: the SQLite file and the stored scans (./var)
    CALF_DATABASE_URL    SQLAlchemy URL; default sqlite:///<data_dir>/calf.db; may be
                         postgresql+psycopg://...
    CALF_WORKERS         fitting worker processes of the embedded runner (2)
    CALF_MAX_UPLOAD_MB   largest scan accepted, counted on the bytes received (200)
    CALF_MAX_JSON_KB     largest JSON request body (1024): checked on Content-Length
                         before the body is read, and on the bytes received
    CALF_MAX_SCAN_POINTS / CALF_MAX_SCAN_FACES
                         most points / triangles in an accepted scan (4M / 4M: a whole
                         body at 1 mm holds ~2M; a calf needs ~50k)
    CALF_JOB_TIMEOUT_S   a fit's time limit (600); its worker process is killed past it
    CALF_JOB_LEASE_S     how long a runner holds a job without renewing it (60): a job
                         whose runner died is taken by another after this
    CALF_JOB_MAX_ATTEMPTS
                         claims of a job whose worker keeps dying before it fails (3)
    CALF_WORKER_MEMORY_MB
                         address-space cap of each check and fit worker process (4096;
                         0: none); a scan that needs more is refused (scan_too_large)
    CALF_TENANT_MAX_JOBS one clinic's jobs queued or running at once (10); past it 429
    CALF_TENANT_MAX_CHECKS / CALF_TENANT_MAX_FITS
                         one clinic's upload checks / fits at once (default: all workers
                         but one, at least one - another clinic always finds one free;
                         with keys off there is one clinic: all workers)
    CALF_BROKER_URL      redis://host:6379/0: fitting jobs go through Dramatiq on Redis and
                         `calf-nurbs worker` runs Dramatiq workers (none: the embedded runner)
    CALF_BROKER_HEARTBEAT_S
                         a Dramatiq worker silent this long is dead: its message is
                         delivered again (60)
    CALF_RUN_JOBS        false: this process accepts uploads but fits nothing (an API
                         container whose jobs a `calf-nurbs worker` process runs)
    CALF_CORS_ORIGINS    JSON list of the web origins allowed to call the API from a
                         browser, e.g. ["https://portal.clinic.example"] (none)
    CALF_HOST            the address the service is bound to (set by `calf-nurbs serve`)
    CALF_RATE_LIMIT      requests per minute per API key (600; 0: no limit), with bursts
                         of CALF_RATE_BURST (100); over it: 429 and Retry-After
    CALF_UPLOAD_RATE_LIMIT
                         uploads per minute per key (30), bursts of CALF_UPLOAD_RATE_BURST (10)
    CALF_IDEMPOTENCY_HOURS
                         how long an Idempotency-Key's first response is kept (24)
    CALF_LOG_LEVEL / CALF_LOG_JSON
                         log level (INFO); JSON lines (true) or plain text (false)
    CALF_API_DOCS        true: serve the interactive API docs at /docs and /redoc (false: they
                         load Swagger UI and ReDoc from a CDN with an inline script, on the
                         origin where the workbench keeps the API key; the contract is
                         openapi/openapi.json and GET /openapi.json)
    CALF_AUTH            required | off.  Default: required, unless the service is bound
                         to localhost (127.0.0.1, ::1, localhost), where it is off and
                         a request without a key acts for the tenant "default" (a key
                         sent is still checked; a warning is logged at start-up).  Keys: `calf-nurbs keys create`.
    """

    model_config = SettingsConfigDict(env_prefix="CALF_", env_file=None)

    data_dir: Path = Path("./var")
    database_url: str | None = None
    workers: int = Field(2, ge=1, le=64)
    max_upload_mb: float = Field(200.0, gt=0)
    max_json_kb: float = Field(1024.0, gt=0)
    max_scan_points: int = Field(4_000_000, ge=1000)
    max_scan_faces: int = Field(4_000_000, ge=1000)
    run_jobs: bool = True
    validation_timeout_s: float = Field(60.0, gt=0)
    job_timeout_s: float = Field(600.0, gt=0)
    job_lease_s: float = Field(60.0, ge=1.0)
    #: how long the service waits at start for its database to answer (a database
    #: server started beside it may not resolve or accept connections yet), s
    db_wait_s: float = Field(30.0, ge=0.0)
    broker_url: str | None = None
    broker_heartbeat_s: float = Field(60.0, ge=1.0)
    broker_namespace: str = "calf-nurbs"
    job_max_attempts: int = Field(3, ge=1, le=20)
    tenant_max_jobs: int = Field(10, ge=1)
    worker_memory_mb: float = Field(4096.0, ge=0)
    tenant_max_checks: int | None = Field(None, ge=1)
    tenant_max_fits: int | None = Field(None, ge=1)
    host: str = "127.0.0.1"
    cors_origins: list[str] = Field(default_factory=list)
    auth: Literal["required", "off"] | None = None
    rate_limit: float = Field(600.0, ge=0)
    rate_burst: int = Field(100, ge=1)
    upload_rate_limit: float = Field(30.0, ge=0)
    upload_rate_burst: int = Field(10, ge=1)
    idempotency_hours: float = Field(24.0, gt=0)
    log_level: Literal["DEBUG", "INFO", "WARNING", "ERROR"] = "INFO"
    log_json: bool = True
    api_docs: bool = False

    @property
    def auth_required(self) -> bool:
        if self.auth is not None:
            return self.auth == "required"
        return self.host not in LOCAL_HOSTS

    @property
    def resolved_database_url(self) -> str:
        if self.database_url:
            return self.database_url
        return f"sqlite:///{(self.data_dir / 'calf.db').resolve()}"

    @property
    def max_upload_bytes(self) -> int:
        return int(self.max_upload_mb * 1024 * 1024)

    @property
    def worker_memory_bytes(self) -> int:
        return int(self.worker_memory_mb * 1024 * 1024)

    @property
    def _share(self) -> int:
        """A clinic's share of the workers: all but one when keys tell clinics apart."""
        return max(1, self.workers - 1) if self.auth_required else self.workers

    @property
    def checks_per_tenant(self) -> int:
        return self.tenant_max_checks or self._share

    @property
    def fits_per_tenant(self) -> int:
        return self.tenant_max_fits or self._share

    @property
    def max_json_bytes(self) -> int:
        return int(self.max_json_kb * 1024)

    @property
    def scan_dir(self) -> Path:
        return self.data_dir / "scans"

    @property
    def tmp_dir(self) -> Path:
        return self.data_dir / "tmp"

    @property
    def placed_dir(self) -> Path:
        """The legs the upload check cut out, each kept until its job's fit reads it
        (app.services.placed_legs)."""
        return self.data_dir / "placed"


@lru_cache
def get_settings() -> Settings:
    return Settings()
