"""The embedded job runner: a process pool fed from the jobs table.

Jobs wait in the database as ``queued``.  A dispatcher task claims at most ``workers``
of them at a time (queued -> running, atomically in the repository), runs
:func:`app.services.fitting.fit_scan_file` in a worker process and stores the outcome
(a record and ``succeeded``, or ``failed`` with the reason).  At start-up, jobs left
``running`` by a crash are put back in the queue, so nothing accepted is ever lost.

The same pool also runs the quick acceptance check of uploads, so neither blocks the
event loop.
"""

from __future__ import annotations

import asyncio
import logging
import multiprocessing
import time
from typing import TYPE_CHECKING
from concurrent.futures import ProcessPoolExecutor
from concurrent.futures.process import BrokenProcessPool

from sqlalchemy.orm import Session, sessionmaker

from app.db.repositories import JobRepository, RecordRepository, ScanRepository
from app.geometry.errors import FitFailure
from app.services.fitting import fit_scan_file
from app.services.records import record_etag
from app.services.storage import ScanStore

if TYPE_CHECKING:
    from app.metrics import Metrics

log = logging.getLogger("calf_nurbs.runner")


class EmbeddedRunner:
    def __init__(self, sessions: sessionmaker[Session], store: ScanStore, workers: int, job_timeout_s: float, run_jobs: bool = True,
                 metrics: Metrics | None = None):
        self.sessions = sessions
        self.metrics = metrics
        self.store = store
        self.workers = workers
        self.job_timeout_s = job_timeout_s
        self.run_jobs = run_jobs
        self.pool: ProcessPoolExecutor | None = None
        self._wakeup: asyncio.Event | None = None
        self._dispatcher: asyncio.Task | None = None
        self._running: set[asyncio.Task] = set()

    # ------------------------------------------------------------------ lifecycle
    async def start(self) -> None:
        self.pool = ProcessPoolExecutor(max_workers=self.workers, mp_context=multiprocessing.get_context("spawn"))
        self._wakeup = asyncio.Event()
        if self.run_jobs:
            requeued = await asyncio.to_thread(self._requeue)
            if requeued:
                log.warning("requeued %d job(s) left running by a previous process", requeued)
            self._dispatcher = asyncio.create_task(self._dispatch_forever(), name="calf-job-dispatcher")

    async def stop(self) -> None:
        if self._dispatcher is not None:
            self._dispatcher.cancel()
            try:
                await self._dispatcher
            except (asyncio.CancelledError, Exception):
                pass
        for task in list(self._running):
            task.cancel()
        if self.pool is not None:
            self.pool.shutdown(wait=True, cancel_futures=True)
            self.pool = None

    def notify(self) -> None:
        """A job was queued: look at the queue now."""
        if self._wakeup is not None:
            self._wakeup.set()

    async def run_in_worker(self, fn, *args, timeout: float | None = None):
        """Run a picklable function in the pool (used for upload checks)."""
        if self.pool is None:
            raise RuntimeError("the runner is not started")
        loop = asyncio.get_running_loop()
        future = loop.run_in_executor(self.pool, fn, *args)
        return await asyncio.wait_for(future, timeout) if timeout else await future

    async def idle(self, timeout: float = 60.0) -> None:
        """Wait until no job is queued or running (tests and benchmarks)."""
        deadline = asyncio.get_running_loop().time() + timeout
        while asyncio.get_running_loop().time() < deadline:
            counts = await asyncio.to_thread(self._counts)
            if not counts.get("queued") and not counts.get("running") and not self._running:
                return
            await asyncio.sleep(0.05)
        raise TimeoutError("jobs still pending")

    # ------------------------------------------------------------------ internals
    def _requeue(self) -> int:
        with self.sessions() as session, session.begin():
            return JobRepository(session).requeue_unfinished()

    def _counts(self) -> dict:
        with self.sessions() as session:
            return JobRepository(session).count_by_status()

    def _claim(self) -> tuple[str, str, str, dict, dict | None] | None:
        with self.sessions() as session, session.begin():
            job = JobRepository(session).claim_next()
            if job is None:
                return None
            scan = ScanRepository(session).get(job.scan_id)
            return job.id, str(self.store.path_for(scan.sha256)), scan.file_format, dict(job.options), job.placement

    def _finish_success(self, job_id: str, outcome: dict) -> None:
        with self.sessions() as session, session.begin():
            jobs = JobRepository(session)
            job = jobs.get(job_id)
            body = outcome["record"]
            record = RecordRepository(session).add(body, record_etag(body), "fit", job.scan_id, owner=job.tenant_id)
            jobs.succeed(job_id, record.id, outcome["stage_seconds"])

    def _finish_failure(self, job_id: str, code: str, detail: str) -> None:
        with self.sessions() as session, session.begin():
            JobRepository(session).fail(job_id, code, detail)

    async def _dispatch_forever(self) -> None:
        assert self._wakeup is not None
        while True:
            try:
                while len(self._running) < self.workers:
                    claimed = await asyncio.to_thread(self._claim)
                    if claimed is None:
                        break
                    task = asyncio.create_task(self._run_job(*claimed))
                    self._running.add(task)
                    task.add_done_callback(self._job_done)
            except Exception:  # a database hiccup must not kill the dispatcher
                log.exception("job dispatch failed; retrying")
                await asyncio.sleep(1.0)
            self._wakeup.clear()
            try:
                await asyncio.wait_for(self._wakeup.wait(), timeout=2.0)
            except asyncio.TimeoutError:
                pass

    def _job_done(self, task: asyncio.Task) -> None:
        self._running.discard(task)
        if self._wakeup is not None:
            self._wakeup.set()

    async def _run_job(self, job_id: str, path: str, file_format: str, options: dict, placement: dict | None) -> None:
        started = time.perf_counter()
        reason = await self._fit_and_store(job_id, path, file_format, options, placement)
        if self.metrics is not None:
            self.metrics.job_ended(time.perf_counter() - started, reason)

    async def _fit_and_store(self, job_id: str, path: str, file_format: str, options: dict, placement: dict | None) -> str | None:
        """Fit one claimed job and store its outcome; the failure code, or None."""
        try:
            outcome = await self.run_in_worker(fit_scan_file, path, file_format, options, placement, timeout=self.job_timeout_s)
        except FitFailure as failure:
            await asyncio.to_thread(self._finish_failure, job_id, failure.reason.value, failure.detail)
            return failure.reason.value
        except asyncio.TimeoutError:
            await asyncio.to_thread(self._finish_failure, job_id, "timeout", f"the fit took longer than {self.job_timeout_s:g} s")
            return "timeout"
        except BrokenProcessPool:
            log.exception("worker process died during job %s", job_id)
            await asyncio.to_thread(self._finish_failure, job_id, "worker_crashed", "the fitting worker process died")
            self._restart_pool()
            return "worker_crashed"
        except asyncio.CancelledError:
            raise  # shutting down: the job stays running and is requeued at the next start
        except Exception:  # a bug: record it on the job rather than lose it
            log.exception("job %s failed unexpectedly", job_id)
            await asyncio.to_thread(self._finish_failure, job_id, "internal_error",
                                    "the fit failed on an unexpected error; it has been logged for the service's operators")
            return "internal_error"
        await asyncio.to_thread(self._finish_success, job_id, outcome)
        return None

    def _restart_pool(self) -> None:
        if self.pool is not None:
            self.pool.shutdown(wait=False, cancel_futures=True)
        self.pool = ProcessPoolExecutor(max_workers=self.workers, mp_context=multiprocessing.get_context("spawn"))
