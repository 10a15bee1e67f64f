"""The upload flow: a received scan is checked in a worker process (the leg placed: its
ankle, calf and knee found) and, when it passes, stored with a queued fitting job.

The router receives the bytes and answers HTTP; this service owns the steps between:
the check (in the clinic's fair share of the check pool, at the priority the clinic's
running tasks leave it), its metrics, and the job's transaction, in which an
idempotent request's answer is staged so that a retry can never queue the job twice.
Nothing is stored when the check fails.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Protocol

from fastapi.concurrency import run_in_threadpool
from fastapi.encoders import jsonable_encoder
from sqlalchemy.orm import Session

from app.errors import TooManyRequests, Unavailable
from app.geometry.errors import FitFailure
from app.services.fitting import validate_scan_file
from app.services.idempotency import Stage
from app.services.jobs import JobService, job_view
from app.services.storage import ScanStore
from app.services.uploads import ReceivedUpload


class CheckRunner(Protocol):
    """What the flow needs of the job runner (app.jobs.runner.EmbeddedRunner)."""

    def busy(self, tenant_id: str | None): ...

    async def run_in_worker(self, fn, *args, timeout: float | None = None): ...

    async def submitted(self, job_id: str) -> None: ...




@dataclass(frozen=True)
class QueuedUpload:
    """The answer to an accepted upload: the job's view (``body``) and its location."""

    body: dict
    location: str


@dataclass
class UploadFlow:
    """Check and queue one clinic's uploads (see the module docstring)."""

    session: Session
    tenant_id: str
    store: ScanStore
    runner: CheckRunner
    check_gate: Any  # app.services.fair_share.CheckGate
    check_seconds: Any  # a prometheus Histogram labelled by outcome
    validation_timeout_s: float
    max_scan_points: int
    max_scan_faces: int

    async def check_and_queue(self, upload: ReceivedUpload, options: dict, stage: Stage | None,
                              case_ref: str | None = None) -> QueuedUpload:
        """Place the leg of ``upload`` in a worker, then store the scan and queue its job
        (the placement travels with the job, and the leg the check cut out is handed to
        it, so the fit neither places it nor reads the scan again:
        app.services.placed_legs).
        Raises FitFailure (the check's reason), Unavailable (check_timeout, the runner
        down) or TooManyRequests (the clinic's checks); the caller discards the file."""
        leg_temp = self.store.placed_leg_temp(upload.temp_path)
        try:
            return await self._check_and_queue(upload, options, stage, case_ref, leg_temp)
        finally:  # handed to the job, or the upload is refused: never left behind
            leg_temp.unlink(missing_ok=True)

    async def _check_and_queue(self, upload: ReceivedUpload, options: dict, stage: Stage | None,
                               case_ref: str | None, leg_temp: Path) -> QueuedUpload:
        started, outcome = time.perf_counter(), "runner_unavailable"
        try:
            async with self.check_gate.slot(self.tenant_id):  # fair share of the check pool
                with self.runner.busy(self.tenant_id) as nice:
                    placement = await self.runner.run_in_worker(
                        validate_scan_file, str(upload.temp_path), upload.file_format, options, self.max_scan_points,
                        self.max_scan_faces, nice, str(leg_temp), timeout=self.validation_timeout_s)
            outcome = "accepted"
        except TimeoutError as exc:
            outcome = "check_timeout"
            raise Unavailable(f"checking the scan took longer than {self.validation_timeout_s:g} s",
                              code="check_timeout") from exc
        except FitFailure as failure:
            outcome = failure.reason.value
            raise
        except TooManyRequests:
            outcome = "too_many_checks"
            raise
        finally:
            self.check_seconds.labels(outcome).observe(time.perf_counter() - started)
        answer: dict = {}

        def keep_answer(job, scan, reused) -> None:  # in the job's transaction
            answer["body"] = jsonable_encoder(job_view(job, scan, reused))
            if stage is not None:
                stage(202, answer["body"], f"/api/v1/jobs/{job.id}")
            # the leg goes to the job before the commit: a runner that claims the job at
            # once finds it (handed over after, a fit that had not waited for it would
            # leave it behind)
            self.store.keep_placed_leg(leg_temp, job.id)
            answer["job_id"] = job.id

        try:
            job, _, _ = await run_in_threadpool(JobService(self.session, self.tenant_id).submit, upload, options,
                                                self.store, placement, keep_answer, case_ref)
        except BaseException:  # no job was stored: nor is its leg
            if "job_id" in answer:
                self.store.remove_placed_legs([answer["job_id"]])
            raise
        await self.runner.submitted(job.id)  # after the commit: a worker never sees an uncommitted job
        return QueuedUpload(answer["body"], f"/api/v1/jobs/{job.id}")
