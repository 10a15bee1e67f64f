"""The embedded job runner: process pools fed from the jobs table.

Jobs wait in the database as ``queued``.  A dispatcher task claims at most ``workers``
of them at a time and runs :func:`app.services.fitting.fit_scan_file` in the *fit pool*;
upload checks run in a *check pool* of their own, so that neither blocks the other nor
the event loop.

Crash safety (every accepted job ends exactly once, as a record or a failure):

- **Leases.**  A claim leases the job to this runner (``owner``: host, pid and a random
  tag) for ``lease_s``; the dispatcher renews the leases of its running jobs every
  ``lease_s / 3``.  Only a job whose lease has expired - its runner died - is claimed by
  another runner; a second runner started beside a live one takes nothing of its.
  A job is finished only by the runner that holds its lease, in the same transaction as
  its record, so a runner whose lease was taken over cannot store a second record.
- **Dead workers.**  A fit whose worker process dies (killed, out of memory) goes back to
  the queue and is retried, up to ``max_attempts`` claims in all; then it fails with the
  reason.  A fit that fails on its input (FitFailure) is not retried.
- **Time limit.**  A fit over ``job_timeout_s`` fails with ``timeout`` (a fit that slow
  would be as slow again), and the fit pool's processes are killed - a process pool
  cannot stop one task - so the slot is free; the other fits that die with them are
  retried.
- **Broken pools.**  A pool whose process died is replaced, once per breakage (a
  generation counter: concurrent failures replace it once), and the upload check that
  met it is run again once.  :meth:`problem` tells ``/readyz`` when the runner cannot run.
"""

from __future__ import annotations

import asyncio
import contextlib
import functools
import gc
import logging
import multiprocessing
import os
import resource
import signal
import sys
import time
from collections import Counter
from collections.abc import Callable
from concurrent.futures import ProcessPoolExecutor
from concurrent.futures.process import BrokenProcessPool
from typing import TYPE_CHECKING

from sqlalchemy.orm import Session, sessionmaker

from app.errors import Unavailable
from app.geometry.errors import FitFailure
from app.jobs import lifecycle
from app.jobs.lifecycle import INTERNAL_ERROR_DETAIL
from app.services.fitting import LIBC, fit_scan_file, warm_up
from app.services.jobs import job_status_counts
from app.services.storage import ScanStore

if TYPE_CHECKING:
    from app.metrics import Metrics

log = logging.getLogger("calf_nurbs.runner")


PR_SET_PDEATHSIG = 1  # linux/prctl.h
#: CPU priority (nice) of a clinic's second and later concurrent tasks: under CFS a task
#: at nice 10 gets about a tenth of the CPU of a nice-0 task it competes with
SECOND_TASK_NICE = 10


def prepare_worker(limit_bytes: int, parent_pid: int) -> None:
    """Pool initializer.  Cap the worker's address space (RLIMIT_AS), so that a scan that
    needs more memory than the limit fails in its own worker with MemoryError (the
    fitting functions turn it into ``scan_too_large``) instead of taking the machine; and
    on Linux have the kernel kill the worker when the process that started it dies
    (prctl PR_SET_PDEATHSIG): a killed API leaves no orphan workers holding memory.
    The pools are started from the event loop's thread, which lives as long as the
    process (the death signal follows the thread that forked)."""
    if limit_bytes > 0:
        resource.setrlimit(resource.RLIMIT_AS, (limit_bytes, limit_bytes))
    if sys.platform.startswith("linux") and LIBC is not None:
        LIBC.prctl(PR_SET_PDEATHSIG, signal.SIGKILL)
        if os.getppid() != parent_pid:  # the parent died before the signal was armed
            os._exit(1)
    # the worker's imports (this module's: numpy, scipy, trimesh, the numerical core, ~120k
    # objects) go to the permanent generation (gc.freeze): the gc.collect that ends every
    # task (app.services.fitting.worker_task, which frees a scan's reference cycles) then
    # walks only what tasks made - 65-70 ms a task less on the Visible Human scans, two
    # tasks (the check and the fit) an upload (benchmarks/bench_service.py)
    gc.freeze()


class _Pool:
    """A process pool that is replaced when one of its processes dies; each worker's
    address space is capped at ``memory_bytes`` (0: no cap)."""

    def __init__(self, name: str, workers: int, memory_bytes: int = 0):
        self.name = name
        self.workers = workers
        self.memory_bytes = memory_bytes
        self.generation = 0
        self.executor: ProcessPoolExecutor | None = None

    def start(self) -> None:
        self.executor = ProcessPoolExecutor(max_workers=self.workers, mp_context=multiprocessing.get_context("spawn"),
                                            initializer=prepare_worker, initargs=(self.memory_bytes, os.getpid()))
        # every worker started now, not on first use: a spawned worker takes ~1 s to
        # import the numerical stack, which a request would otherwise wait for (the
        # executor starts a process per submission while none is idle)
        for _ in range(self.workers):
            self.executor.submit(warm_up)

    def replace(self, generation: int) -> None:
        """Replace the pool if it is still the ``generation`` that broke."""
        if generation != self.generation:
            return
        self.kill()
        self.generation += 1
        self.start()
        log.warning("the %s pool was replaced (a worker process died or was stopped)", self.name)

    def kill(self) -> None:
        """Stop the pool now, its running tasks with it (their futures break)."""
        pids, executor, self.executor = self.pids(), self.executor, None
        if executor is None:
            return
        for pid in pids:
            try:
                os.kill(pid, signal.SIGKILL)
            except OSError:  # already gone
                pass
        executor.shutdown(wait=False, cancel_futures=True)

    def pids(self) -> list[int]:
        """The pool's worker processes (ProcessPoolExecutor keeps them in _processes)."""
        return [p.pid for p in list((getattr(self.executor, "_processes", None) or {}).values())]

    async def run(self, fn, *args, timeout: float | None = None):
        if self.executor is None:
            raise Unavailable("the fitting workers are not running", code="runner_unavailable")
        future = asyncio.get_running_loop().run_in_executor(self.executor, fn, *args)
        return await asyncio.wait_for(future, timeout) if timeout else await future


class EmbeddedRunner:
    def __init__(self, sessions: sessionmaker[Session], store: ScanStore, workers: int, job_timeout_s: float, run_jobs: bool = True,
                 metrics: Metrics | None = None, lease_s: float = 60.0, max_attempts: int = 3,
                 enqueue: Callable[[str], None] | None = None, worker_memory_bytes: int = 0,
                 fits_per_tenant: int | None = None):
        self.sessions = sessions
        self.store = store
        self.workers = workers
        self.job_timeout_s = job_timeout_s
        self.run_jobs = run_jobs
        self.metrics = metrics
        self.lease_s = lease_s
        self.max_attempts = max_attempts
        #: broker mode (app.jobs.dramatiq_queue.send): fits are sent to Dramatiq workers,
        #: this process only checks uploads
        self.enqueue = enqueue
        if enqueue is not None:
            self.run_jobs = False
        self.owner = lifecycle.owner_name()
        #: at most this many of one clinic's fits at once (app.services.fair_share); None: any
        self.fits_per_tenant = fits_per_tenant
        self.check_pool = _Pool("check", workers, worker_memory_bytes)
        self.fit_pool = _Pool("fit", workers, worker_memory_bytes)
        self._wakeup: asyncio.Event | None = None
        self._dispatcher: asyncio.Task | None = None
        self._running: dict[str, asyncio.Task] = {}
        #: checks and fits running here, per tenant (their CPU priority: priority_for)
        self._busy: Counter = Counter()
        self._renewed = 0.0

    # ------------------------------------------------------------------ lifecycle
    async def start(self) -> None:
        self.check_pool.start()
        self._wakeup = asyncio.Event()
        if self.enqueue is not None:
            # queued jobs whose message was never sent (the process died between the
            # commit and the send): send them now; a duplicate message ends its job once
            for job_id in await asyncio.to_thread(lifecycle.queued_job_ids, self.sessions):
                await asyncio.to_thread(self.enqueue, job_id)
        if self.run_jobs:
            self.fit_pool.start()
            self._dispatcher = asyncio.create_task(self._dispatch_forever(), name="calf-job-dispatcher")

    async def stop(self) -> None:
        if self._dispatcher is not None:
            self._dispatcher.cancel()
            try:
                await self._dispatcher
            except (asyncio.CancelledError, Exception):
                pass
        for task in list(self._running.values()):
            task.cancel()
        # jobs still running stay leased to this runner and are taken over when the
        # lease expires; a clean stop hands them back at once
        if self._running:
            await asyncio.to_thread(self._release_all, list(self._running))
        for pool in (self.check_pool, self.fit_pool):
            if pool.executor is not None:
                pool.executor.shutdown(wait=True, cancel_futures=True)
                pool.executor = None

    def problem(self) -> str | None:
        """Why the runner cannot run jobs or checks now, or None."""
        if self.check_pool.executor is None:
            return "the upload check workers are not running"
        if self.run_jobs and (self._dispatcher is None or self._dispatcher.done()):
            return "the job dispatcher has stopped"
        if self.run_jobs and self.fit_pool.executor is None:
            return "the fitting workers are not running"
        return None

    def notify(self) -> None:
        """A job was queued: look at the queue now."""
        if self._wakeup is not None:
            self._wakeup.set()

    async def submitted(self, job_id: str) -> None:
        """A job was committed to the queue: send it to the broker, or wake the dispatcher."""
        if self.enqueue is not None:
            await asyncio.to_thread(self.enqueue, job_id)
        else:
            self.notify()

    def priority_for(self, tenant_id: str | None) -> int:
        """CPU priority of a new task of ``tenant_id``: 0 while the clinic has no other
        check or fit running here, else SECOND_TASK_NICE - on a machine with as many
        cores as workers, a clinic's second task then yields the CPU to another
        clinic's first (measured: benchmarks/results/hostile.md), and with no one else
        busy it runs at full speed all the same (nice only orders contention)."""
        return 0 if not tenant_id or not self._busy[tenant_id] else SECOND_TASK_NICE

    @contextlib.contextmanager
    def busy(self, tenant_id: str | None):
        """Count a task of ``tenant_id`` as running here while the block runs; yields
        the task's CPU priority (:meth:`priority_for`, before it is counted)."""
        nice = self.priority_for(tenant_id)
        if tenant_id:
            self._busy[tenant_id] += 1
        try:
            yield nice
        finally:
            if tenant_id:
                self._busy[tenant_id] -= 1

    async def run_in_worker(self, fn, *args, timeout: float | None = None):
        """Run a picklable function in the check pool (upload checks).  A broken pool is
        replaced and the call made once more; a second breakage answers 503."""
        for attempt in (1, 2):
            generation = self.check_pool.generation
            try:
                return await self.check_pool.run(fn, *args, timeout=timeout)
            except BrokenProcessPool:
                self.check_pool.replace(generation)
                if attempt == 2:
                    raise Unavailable("the upload check's worker process stopped twice; try again in a moment",
                                      code="runner_unavailable") from None
            except TimeoutError:
                self.check_pool.replace(generation)  # the slow check's process must not keep its slot
                raise

    async def idle(self, timeout: float = 60.0) -> None:
        """Wait until no job is queued or running (tests and benchmarks)."""
        deadline = asyncio.get_running_loop().time() + timeout
        while asyncio.get_running_loop().time() < deadline:
            counts = await asyncio.to_thread(self._counts)
            if not counts.get("queued") and not counts.get("running") and not self._running:
                return
            await asyncio.sleep(0.05)
        raise TimeoutError("jobs still pending")

    # ------------------------------------------------------------------ database
    def _counts(self) -> dict:
        with self.sessions() as session:
            return job_status_counts(session)

    def _claim(self):
        return lifecycle.claim(self.sessions, self.store, self.owner, self.lease_s, self.max_attempts,
                               per_tenant=self.fits_per_tenant)

    def _release_all(self, job_ids: list[str]) -> None:
        for job_id in job_ids:
            lifecycle.release(self.sessions, self.owner, job_id)

    # ------------------------------------------------------------------ dispatch
    async def _dispatch_forever(self) -> None:
        assert self._wakeup is not None
        while True:
            try:
                if self._running and time.monotonic() - self._renewed > self.lease_s / 3:
                    await asyncio.to_thread(lifecycle.renew, self.sessions, self.owner, list(self._running), self.lease_s)
                    self._renewed = time.monotonic()
                while len(self._running) < self.workers:
                    claimed = await asyncio.to_thread(self._claim)
                    if claimed is None:
                        break
                    if claimed == lifecycle.EXHAUSTED:
                        continue
                    job_id = claimed.job_id
                    task = asyncio.create_task(self._run_job(claimed))
                    self._running[job_id] = task
                    task.add_done_callback(lambda _t, j=job_id: self._job_done(j))
            except Exception:  # a database hiccup must not kill the dispatcher
                log.exception("job dispatch failed; retrying")
                await asyncio.sleep(1.0)
            self._wakeup.clear()
            try:
                await asyncio.wait_for(self._wakeup.wait(), timeout=min(2.0, self.lease_s / 3))
            except TimeoutError:
                pass

    def _job_done(self, job_id: str) -> None:
        self._running.pop(job_id, None)
        if self._wakeup is not None:
            self._wakeup.set()

    async def _run_job(self, job: lifecycle.ClaimedJob) -> None:
        started = time.perf_counter()
        reason = await self._fit_and_store(job)
        if self.metrics is not None and reason != "retried":
            self.metrics.job_ended(time.perf_counter() - started, reason)

    async def _fit_and_store(self, job: lifecycle.ClaimedJob) -> str | None:
        """Fit one claimed job and store its outcome; the failure code, None for a
        record, or "retried" when the job went back to the queue."""
        generation = self.fit_pool.generation
        conclude = functools.partial(asyncio.to_thread, lifecycle.conclude, self.sessions, self.owner, job.job_id)
        try:
            with self.busy(job.tenant_id) as nice:
                outcome = await self.fit_pool.run(fit_scan_file, job.path, job.file_format, job.options, job.placement,
                                                  nice, job.placed_leg, timeout=self.job_timeout_s)
        except FitFailure as failure:
            return await conclude(failure=failure)
        except TimeoutError:
            self.fit_pool.replace(generation)  # its process is killed: the slot is free again
            return await conclude(timeout_s=self.job_timeout_s)
        except BrokenProcessPool:
            log.warning("the worker process of job %s died; the job goes back to the queue", job.job_id)
            self.fit_pool.replace(generation)
            await asyncio.to_thread(lifecycle.release, self.sessions, self.owner, job.job_id)
            return "retried"
        except asyncio.CancelledError:
            raise  # shutting down: stop() hands the job back
        except Exception:  # a bug: record it on the job rather than lose it
            log.exception("job %s failed unexpectedly", job.job_id)
            await asyncio.to_thread(lifecycle.fail, self.sessions, self.owner, job.job_id, "internal_error",
                                    INTERNAL_ERROR_DETAIL)
            return "internal_error"
        return await conclude(outcome=outcome)
