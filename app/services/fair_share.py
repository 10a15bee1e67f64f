"""Fair share of the machine between clinics: no clinic can hold the service from others.

Four bounds, each per tenant (a clinic):

- **Jobs** (:meth:`app.services.jobs.JobService.ensure_capacity`): at most CALF_TENANT_MAX_JOBS of a tenant's jobs
  queued or running at once - uploads' fits and populations' refits alike.  Past it the
  upload (or the population's extra refits) is refused with 429 ``too_many_jobs`` and
  Retry-After, before the scan is received or checked.
- **Upload checks** (:class:`CheckGate`): at most CALF_TENANT_MAX_CHECKS of a tenant's
  upload checks run in the check pool at once (default: all workers but one, at least
  one; with keys off all), so another clinic's check always finds a worker free of the
  first clinic's;
  a tenant's further checks wait for its own slot (costing nothing: the scan is on disk),
  and after CALF_VALIDATION_TIMEOUT_S are refused with 429 ``too_many_checks``.
- **Fits**: the embedded runner claims the oldest queued job of the tenant with the
  fewest running fits, and none of a tenant already running CALF_TENANT_MAX_FITS
  (default: all workers but one) (:meth:`app.db.repositories.JobRepository.claim_next`),
  so a clinic that uploads while another's queue is full finds a fit worker free.
- **CPU**: a clinic's second concurrent check or fit runs at nice
  :data:`app.jobs.runner.SECOND_TASK_NICE` (:meth:`app.jobs.runner.EmbeddedRunner.priority_for`):
  with as many workers as cores, the first clinic's check and fit would otherwise take
  both cores from another clinic's upload (measured 3.2x its idle time); nice orders
  contention only, so a clinic alone still runs at full speed.

With keys off (a service bound to localhost) every request is the one tenant
``default``: there is nothing to share, and the check and fit bounds default to every
worker.  (Dramatiq workers take messages in the broker's order; the job bound above
bounds what one clinic can put ahead of another there.)
"""

from __future__ import annotations

import asyncio
import contextlib
from collections import defaultdict

from app.errors import TooManyRequests

#: what a refused clinic is told to wait: about one fit
RETRY_AFTER_S = 5


def too_many_jobs(limit: int) -> TooManyRequests:
    return TooManyRequests(
        f"your clinic already has {limit} scans queued or being fitted, the most one clinic may have at once; "
        f"send the next when one has finished (about {RETRY_AFTER_S} s)", retry_after_s=RETRY_AFTER_S,
        code="too_many_jobs", extra={"limit": limit})


class CheckGate:
    """Per-tenant slots of the upload check pool (module docstring)."""

    def __init__(self, per_tenant: int, wait_s: float):
        self.per_tenant = per_tenant
        self.wait_s = wait_s
        self._slots: dict[str, asyncio.Semaphore] = defaultdict(lambda: asyncio.Semaphore(self.per_tenant))

    @contextlib.asynccontextmanager
    async def slot(self, tenant_id: str):
        semaphore = self._slots[tenant_id]
        try:
            await asyncio.wait_for(semaphore.acquire(), self.wait_s)
        except TimeoutError:
            raise TooManyRequests(
                f"your clinic's uploads have waited {self.wait_s:g} s for a check: {self.per_tenant} of them may be "
                "checked at once; send fewer at a time", retry_after_s=RETRY_AFTER_S, code="too_many_checks",
                extra={"limit": self.per_tenant}) from None
        try:
            yield
        finally:
            semaphore.release()
