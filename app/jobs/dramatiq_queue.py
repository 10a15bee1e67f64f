"""Scale-out: fitting jobs through Dramatiq on Redis (``CALF_BROKER_URL=redis://...``).

Imported only when a broker is configured: it sets Dramatiq's broker at import (the
actor is declared on it), in the API process (which sends) and in every worker process
(``calf-nurbs worker`` runs ``dramatiq app.jobs.dramatiq_queue``).

- The jobs table stays the source of truth; a message carries only the job id, and is
  sent after the upload's transaction has committed.  A job is claimed, leased and
  finished by :mod:`app.jobs.lifecycle`, the same code the embedded runner uses: a
  message delivered twice (a redelivery, the API re-sending queued jobs at start-up)
  ends its job once.
- Dramatiq's own machinery does the rest: its Redis broker redelivers the unacknowledged
  message of a worker that died (after ``CALF_BROKER_HEARTBEAT_S`` without a heartbeat);
  its Retries middleware retries a fit that failed on an unexpected error, and a
  delivery that found the job still leased to a worker (which may have died: the lease
  runs out), with backoff; its TimeLimit middleware stops a fit over
  ``CALF_JOB_TIMEOUT_S``.
- The fit runs in the Dramatiq worker process itself (one thread per process: the fit
  is numerical work, parallel across processes, not threads).  A lease keeper thread
  renews the job's lease while it runs.
"""

from __future__ import annotations

import logging
import os
import threading

import dramatiq
from dramatiq.brokers.redis import RedisBroker
from dramatiq.middleware import TimeLimitExceeded

from app.db.session import session_factory
from app.geometry.errors import FitFailure
from app.jobs import lifecycle
from app.services.fitting import fit_scan_file
from app.services.storage import ScanStore
from app.settings import Settings, get_settings

log = logging.getLogger("calf_nurbs.dramatiq")
QUEUE = "calf-fits"
#: Redis broker queue maintenance (requeueing a dead worker's messages) runs on this
#: many commands in a million; Dramatiq's default (1000) can leave a dead worker's job
#: waiting for minutes on an idle queue
MAINTENANCE_CHANCE = 100_000
#: a delivery that finds its job leased to another worker retries for this many times,
#: the backoff growing to the lease time: long enough for a dead worker's lease to lapse
MAX_RETRIES = 20


class LeaseHeld(Exception):
    """The job is leased to another worker now; try again later (Dramatiq retries)."""


def make_broker(settings: Settings) -> RedisBroker:
    return RedisBroker(url=settings.broker_url, heartbeat_timeout=int(settings.broker_heartbeat_s * 1000),
                       maintenance_chance=MAINTENANCE_CHANCE, namespace=settings.broker_namespace)


_settings = get_settings()
broker = make_broker(_settings)
dramatiq.set_broker(broker)


class _Context:
    """This worker process's database sessions, scan store and lease owner name."""

    def __init__(self, settings: Settings):
        self.settings = settings
        self.sessions = session_factory(settings.resolved_database_url)
        self.store = ScanStore(settings.scan_dir, settings.tmp_dir, settings.placed_dir)
        self.pid = os.getpid()
        self.owner = lifecycle.owner_name()


_context: _Context | None = None
_context_lock = threading.Lock()


def _worker_context() -> _Context:
    global _context
    with _context_lock:
        if _context is None or _context.pid != os.getpid():  # a forked worker makes its own
            _context = _Context(get_settings())
        return _context


class _LeaseKeeper:
    """Renews a job's lease every third of the lease time while the fit runs."""

    def __init__(self, context: _Context, job_id: str):
        self.context, self.job_id = context, job_id
        self.stopped = threading.Event()
        self.thread = threading.Thread(target=self._run, name=f"lease-{job_id[:8]}", daemon=True)

    def _run(self) -> None:
        lease_s = self.context.settings.job_lease_s
        while not self.stopped.wait(lease_s / 3):
            try:
                lifecycle.renew(self.context.sessions, self.context.owner, [self.job_id], lease_s)
            except Exception:  # the next renewal tries again; the lease lasts 3 periods
                log.exception("renewing the lease of job %s failed", self.job_id)

    def __enter__(self):
        self.thread.start()
        return self

    def __exit__(self, *exc):
        self.stopped.set()
        self.thread.join(timeout=5)


def _retry_when(retries: int, exception: BaseException) -> bool:
    return retries < MAX_RETRIES and not isinstance(exception, (FitFailure, TimeLimitExceeded))


@dramatiq.actor(queue_name=QUEUE, actor_name="fit_job", max_retries=MAX_RETRIES, retry_when=_retry_when,
                min_backoff=500, max_backoff=int(_settings.job_lease_s * 1000),
                time_limit=int(_settings.job_timeout_s * 1000))
def fit_job(job_id: str) -> None:
    """Fit the job ``job_id`` (the one job function of the module docstring)."""
    context = _worker_context()
    settings = context.settings
    claimed = lifecycle.claim(context.sessions, context.store, context.owner, settings.job_lease_s,
                              settings.job_max_attempts, job_id=job_id)
    if claimed is None:
        if lifecycle.status(context.sessions, job_id) == "running":
            raise LeaseHeld(f"job {job_id} is leased to another worker")
        return  # finished already (a second delivery), or deleted
    if claimed == lifecycle.EXHAUSTED:
        return
    with _LeaseKeeper(context, job_id):
        try:
            outcome = fit_scan_file(claimed.path, claimed.file_format, claimed.options, claimed.placement,
                                    placed_leg=claimed.placed_leg)
        except FitFailure as failure:
            lifecycle.conclude(context.sessions, context.owner, job_id, failure=failure)
            return
        except TimeLimitExceeded:
            lifecycle.conclude(context.sessions, context.owner, job_id, timeout_s=settings.job_timeout_s)
            return
        except Exception:
            log.exception("job %s failed unexpectedly; Dramatiq retries it", job_id)
            lifecycle.release(context.sessions, context.owner, job_id)
            raise
    lifecycle.conclude(context.sessions, context.owner, job_id, outcome=outcome)


def send(job_id: str) -> None:
    fit_job.send(job_id)
